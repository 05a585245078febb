# bench tradeoff at 2x720x800 (fixed view + head pose 0), then bench budget at 2x1440x1600, per scene, into $OUT/r
# usage: trade.sh "tradeoff default 280" "budget default 2048 330" ...
. .gpu/setup.sh > $OUT/device_smi.txt
export RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r; cp $OUT/device_smi.txt $OUT/r/device.txt; echo $RAYVR_COMMIT > $OUT/r/commit.txt
for job in "$@"; do
  set -- $job
  if [ $1 = tradeoff ]; then
    ( time timeout $3 python3 -m rayvr bench tradeoff --scenes $2 --size 720x800 --poses 1 --repeat 10 --out $OUT/r/tradeoff ) 2>&1 | tr '\r' '\n' | grep -v '%|' > $OUT/r/tradeoff_$2.log; echo "tradeoff $2 rc=${PIPESTATUS[0]}"
  else
    ( time timeout $4 python3 -m rayvr bench budget --scenes $2 --poses 1 --repeat 25 --reference-spp $3 \
       --frame-knobs "stereo=dual,reuse;spp=1,4;denoise=off,on" --rung-params "glossy.samples=1,16;path.samples=4" \
       --out $OUT/r/budget ) 2>&1 | tr '\r' '\n' | grep -v '%|' > $OUT/r/budget_$2.log; echo "budget $2 rc=${PIPESTATUS[0]}"
    rm -f $OUT/r/budget/budget_*_8.333ms.png $OUT/r/budget/budget_*pose*ms.png
  fi
  tail -4 $OUT/r/$1_$2.log
done
tar czf $OUT/results.tgz -C $OUT r && rm -rf $OUT/r
