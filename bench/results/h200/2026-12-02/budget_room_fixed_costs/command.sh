# bench budget on one scene: fixed view + head pose 0, at 2x1440x1600; $1 scene, $2 reference spp, $3 timeout
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
( time timeout $3 python3 -m rayvr bench budget --scenes $1 --poses 1 --repeat 25 --reference-spp $2 \
   --frame-knobs "stereo=dual,reuse;spp=1,4;denoise=off,on" --rung-params "glossy.samples=1,16;path.samples=4" \
   --out $OUT/r/budget_$1 ) > $OUT/r/budget_$1.log 2>&1; echo "rc=$?"
tail -25 $OUT/r/budget_$1.log
rm -f $OUT/r/budget_$1/*pick*.png
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
