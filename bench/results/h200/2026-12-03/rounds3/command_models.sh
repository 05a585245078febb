# foveated and wide at 1/4/16x, 3 poses seed 22 (the poses of 2026-12-02/vr), code after the merge fast path and round tiles
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 150 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras foveated,wide_210x130 --counts 1,4,16 --repeat 10 --out $OUT/r/vr_models > $OUT/r/vr_models.log 2>&1; echo "models rc=$?"
f=$OUT/r/vr_models/vr.md; sed -n '/^| config/,/^$/p' $f | cut -d'|' -f4,7,9,10,12,14
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
