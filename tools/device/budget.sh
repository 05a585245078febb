# bench budget at 2x1440x1600, the frame-wide grid stereo x denoise x resolution scale, one scene a
# call (its reference size differs), into $OUT/r/budget/SCENE, packed as $OUT/r_PID.tgz.
# Usage: bash .gpu/budget.sh SCENE REFERENCE_SPP VIEWS TIMEOUT_S   (e.g. default 2048 fixed,0 540)
. .gpu/setup.sh $OUT/r
( time timeout $4 python3 -m rayvr bench budget --scenes $1 --only-views $3 --repeat 25 --reference-spp $2 \
   --frame-knobs "stereo=dual,reuse;spp=1;denoise=off,on;scale=0.5,1" \
   --rung-params "glossy.samples=1,16;path.samples=4" --out $OUT/r/budget/$1 ) 2>&1 |
  tr '\r' '\n' | grep -v '%|' > $OUT/r/budget_$1.log
echo "budget $1 rc=${PIPESTATUS[0]}"
rm -f $OUT/r/budget/$1/budget_*_8.333ms.png $OUT/r/budget/$1/budget_*pose*ms.png
tail -6 $OUT/r/budget_$1.log
