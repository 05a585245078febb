# final call A: the suite with -n 6, then compact benches of this session's work (results tarred: 8 files come back)
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
timeout 220 python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -2 $OUT/r/suite_n6.log
grep -E "^(FAILED|ERROR)" $OUT/r/suite_n6.log | head -10
S=.shared/scenes/sponza_dabrovic/sponza.obj
( time timeout 40 python3 -m rayvr capture --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 48 --out /tmp/cap_room -q ) > $OUT/r/capture_room.log 2>&1; echo "capture room rc=$?"; tail -4 $OUT/r/capture_room.log
( time timeout 30 python3 -m rayvr capture --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 24 --writers 1 --out /tmp/cap_room1 -q ) > $OUT/r/capture_room_writers1.log 2>&1; echo "capture room writers=1 rc=$?"; tail -4 $OUT/r/capture_room_writers1.log
( time timeout 25 python3 -m rayvr capture $S --size 1440x1600 --frames 48 --out /tmp/cap_sponza -q ) > $OUT/r/capture_sponza.log 2>&1; echo "capture sponza rc=$?"; tail -4 $OUT/r/capture_sponza.log
( time timeout 30 python3 -m rayvr capture --views sphere:256 --eye left --size 800x800 --out /tmp/cap_views -q ) > $OUT/r/capture_views.log 2>&1; echo "capture views rc=$?"; tail -4 $OUT/r/capture_views.log
timeout 70 python3 -m rayvr bench rays --scenes default,sponza --layouts bvh2,cwbvh --no-tiles --repeat 10 --out $OUT/r/rays > $OUT/r/rays.log 2>&1; echo "rays rc=$?"; grep -E "GRays" $OUT/r/rays.log | grep -v "bvh2 rows" | cut -c1-110
timeout 40 python3 -m rayvr bench vr --scenes default,sponza --poses 5 --configs shadows,room --counts 1 --cameras pinhole --repeat 25 --traversal cwbvh --out $OUT/r/vr_cwbvh > $OUT/r/vr_cwbvh.log 2>&1; echo "vr cwbvh rc=$?"
grep -E "^\| (shadows|room)" $OUT/r/vr_cwbvh/vr.md | cut -d'|' -f2,3,4,8,9,13
timeout 30 python3 -m rayvr bench lights --scenes default --poses 1 --repeat 25 --out $OUT/r/lights > $OUT/r/lights.log 2>&1; echo "lights rc=$?"; grep -E "K=" $OUT/r/lights.log | tail -8
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
