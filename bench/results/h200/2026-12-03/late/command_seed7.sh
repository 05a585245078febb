# call D (~200 s): bench vr's targets on a second pose seed (7, 3 poses)
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 200 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --pose-seed 7 --configs shadows,room --cameras pinhole,distorted_chromatic --counts 1,4,16,32 --repeat 10 --out $OUT/r/vr_seed7 > $OUT/r/vr_seed7.log 2>&1; echo "vr rc=$?"
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
