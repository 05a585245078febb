# the suite with -n 6, then bench vr's targets (pinhole and distorted chromatic, 1/4/16/32x, both scenes)
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 300 python3 -m pytest -n 6 -q --tb=short -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -n 1 $OUT/r/suite_n6.log
grep -E "(FAILED|ERROR)" $OUT/r/suite_n6.log | head -10
timeout 230 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras pinhole,distorted_chromatic --counts 1,4,16,32 --repeat 10 --out $OUT/r/vr_final > $OUT/r/vr_final.log 2>&1; echo "vr rc=$?"
grep -A8 "^| target" $OUT/r/vr_final/vr.md
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
