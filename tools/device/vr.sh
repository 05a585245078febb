# bench vr of the headset frame by this tree's rayvr and, beside it on the same machine, by an older
# commit's (prepare.sh OLD=COMMIT unpacks its rayvr/ into .old/ with this tree's head poses, so both
# time the same heads), into $OUT/v/{new,old}, packed as $OUT/v_PID.tgz.
# Usage: bash .gpu/vr.sh TIMEOUT_S WHICH BENCH_VR_ARGS...   (WHICH: new, old or both)
. .gpu/setup.sh $OUT/v
limit=$1 which=$2; shift 2
for tree in new old; do
  [ "$which" = both ] || [ "$which" = $tree ] || continue
  root=$PWD; [ $tree = old ] && root=$PWD/.old
  [ -e $root/.gpu ] || ln -s $PWD/.gpu $root/.gpu
  ( cd $root && time PYTHONPATH=/tmp/site:$root timeout $limit python3 -m rayvr bench vr "$@" --out $OUT/v/$tree ) 2>&1 |
    tr '\r' '\n' | grep -v '%|' > $OUT/v/vr_$tree.log
  echo "vr $tree rc=${PIPESTATUS[0]}"; tail -3 $OUT/v/vr_$tree.log
done
