# call A: the suite with -n 6, then bench vr (default variant, and tile lists) at 2x1440x1600
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
timeout ${1:-200} python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -3 $OUT/suite_n6.log
grep -E "FAILED|ERROR" $OUT/suite_n6.log | head -10
timeout ${2:-200} python3 -m rayvr bench vr --scenes default,sponza --poses 3 --counts 1,4,16 --cameras raster_gbuffer,pinhole,distorted_chromatic,foveated,wide_210x130,dof_0.5m --configs shadows,room --repeat 8 --out $OUT/vr > $OUT/bench.log 2>&1; echo "vr rc=$?"
timeout ${3:-100} python3 -m rayvr bench vr --scenes default,sponza --poses 3 --counts 1,16 --cameras pinhole,distorted_chromatic --configs shadows --tile-lists 256 --repeat 8 --out $OUT/vr_lists >> $OUT/bench.log 2>&1; echo "vr lists rc=$?"
