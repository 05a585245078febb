# call: warm shader cache, then writers 8/12/16 twice each interleaved (room), views 8/16, then serial suite half 1
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
R="--size 1440x1600 --frames 48"
V="--views sphere:256 --eye left --size 800x800"
run() { n=$1; shift; ( time timeout 40 python3 -m rayvr capture "$@" --timings ) > $OUT/r/$n.log 2>&1; cp $(echo "$@" | grep -o '/tmp/[a-z0-9_]*')/frame_timings.json $OUT/r/$n.timings.json; echo "$n rc=$?"; tr '\r' '\n' < $OUT/r/$n.log | grep -E "frame/s" | tail -1 | cut -c1-160; }
run warm $R --frames 4 --out /tmp/warm
for rep in 1 2; do for w in 8 12 16; do run room_w${w}_r$rep $R --writers $w --out /tmp/room_w${w}_r$rep; done; done
for w in 8 16; do run views_w$w $V --writers $w --out /tmp/views_w$w; done
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
timeout 340 python3 -m pytest -q -p no:cacheprovider $(cat .gpu/serial_half1.txt) > $OUT/suite_serial1.log 2>&1; echo "serial1 rc=$?"; tail -2 $OUT/suite_serial1.log
grep -E "^(FAILED|ERROR)" $OUT/suite_serial1.log | head -10
