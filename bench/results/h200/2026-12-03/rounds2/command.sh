# bench (shared groups, merge fast path, round gate, round tiles) then the suite with -n 6
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 150 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras distorted_chromatic --counts 1,4,16 --variants "shared:;apart:share_channel_shading=off" --repeat 10 --out $OUT/r/vr_shared > $OUT/r/vr_shared.log 2>&1; echo "shared rc=$?"
timeout 100 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras pinhole --counts 1,4,16 --repeat 10 --out $OUT/r/vr_pinhole > $OUT/r/vr_pinhole.log 2>&1; echo "pinhole rc=$?"
for f in $OUT/r/vr_*/vr.md; do echo "== $f"; sed -n '/^| config/,/^$/p' $f | cut -d'|' -f3-5,7,9,10,12,14; grep "^- shadows" $f; done
timeout 320 python3 -m pytest -n 6 -v --tb=short -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -n 1 $OUT/r/suite_n6.log
grep -E "(FAILED|ERROR)" $OUT/r/suite_n6.log | head -20
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
