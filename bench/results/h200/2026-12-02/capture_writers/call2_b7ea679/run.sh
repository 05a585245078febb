# call: issue 24 writers sweep (default = half the cores) and the suite -n 6
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
S=.shared/scenes/sponza_dabrovic/sponza.obj
run() { n=$1; shift; ( time timeout 40 python3 $PY -m rayvr capture "$@" --timings ) > $OUT/r/$n.log 2>&1; echo "$n rc=$?"; tr '\r' '\n' < $OUT/r/$n.log | grep -E "frame/s" | tail -1 | cut -c1-160; }
R="--size 1440x1600 --frames 48"
V="--views sphere:256 --eye left --size 800x800"
run room_default $R --out /tmp/d1
run room_w12 $R --writers 12 --out /tmp/d2
run room_w6 $R --writers 6 --out /tmp/d3
PY="-X importtime" ; PY=""
cat > /tmp/si.py <<'P'
import sys, runpy; sys.setswitchinterval(0.0005); sys.argv = ["rayvr"] + sys.argv[1:]; runpy.run_module("rayvr", run_name="__main__")
P
( time timeout 40 python3 /tmp/si.py capture $R --writers 16 --timings --out /tmp/d4 ) > $OUT/r/room_w16_si05.log 2>&1; echo "si rc=$?"; tr '\r' '\n' < $OUT/r/room_w16_si05.log | grep -E "frame/s" | tail -1 | cut -c1-160
run sponza_default $S $R --out /tmp/d5
run views_default $V --out /tmp/d6
run views_w12 $V --writers 12 --out /tmp/d7
run views_w4 $V --writers 4 --out /tmp/d8
for d in d1 d2 d3 d4 d5 d6 d7 d8; do cp /tmp/$d/frame_timings.json $OUT/r/$d.timings.json 2>/dev/null; done
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
timeout 380 python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -2 $OUT/suite_n6.log
grep -E "^(FAILED|ERROR)" $OUT/suite_n6.log | head -10
