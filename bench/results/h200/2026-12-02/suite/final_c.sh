# call: capture pipeline figures (timings, progress bar), bench lights on both scenes, bench rays on Sponza
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
S=.shared/scenes/sponza_dabrovic/sponza.obj
run() { n=$1; shift; ( time timeout 40 python3 -m rayvr capture "$@" --timings ) > $OUT/r/$n.log 2>&1; echo "$n rc=$?"; tr '\r' '\n' < $OUT/r/$n.log | grep -E "frame/s|frames/s|it/s|real|pipeline|GPU .*ms/frame" | tail -4; }
run cap_room --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 48 --out /tmp/c1
run cap_room_w1 --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 48 --writers 1 --out /tmp/c2
run cap_sponza $S --size 1440x1600 --frames 48 --out /tmp/c3
run cap_sponza_w1 $S --size 1440x1600 --frames 48 --writers 1 --png-compression 6 --out /tmp/c4
run cap_views --views sphere:256 --eye left --size 800x800 --out /tmp/c5
for d in c1 c2 c3 c4 c5; do cp /tmp/$d/frame_timings.json $OUT/r/$d.timings.json 2>/dev/null; done
timeout 70 python3 -m rayvr bench lights --scenes default,sponza --poses 2 --repeat 25 --out $OUT/r/lights > $OUT/r/lights.log 2>&1; echo "lights rc=$?"; grep -E "K=" $OUT/r/lights.log
timeout 100 python3 -m rayvr bench rays --scenes sponza --layouts bvh2,cwbvh --no-tiles --repeat 10 --out $OUT/r/rays > $OUT/r/rays.log 2>&1; echo "rays rc=$?"; grep -E "GRays" $OUT/r/rays.log | grep -v "bvh2 rows" | cut -c1-100
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
