# bench tradeoff --knobs path_everywhere,temporal into a copy of the committed tradeoff folder (its other rows stay)
. .gpu/setup.sh > $OUT/device_smi.txt
export RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r; cp $OUT/device_smi.txt $OUT/r/device.txt; echo $RAYVR_COMMIT > $OUT/r/commit.txt
cp -r bench/results/h200/2026-12-04/trade/tradeoff $OUT/r/tradeoff
( time timeout 330 python3 -m rayvr bench tradeoff --scenes default,sponza --knobs path_everywhere,temporal --size 720x800 --poses 1 --repeat 10 --out $OUT/r/tradeoff ) 2>&1 | tr '\r' '\n' | grep -v '%|' > $OUT/r/tradeoff_knobs.log; echo "rc=${PIPESTATUS[0]}"
tail -5 $OUT/r/tradeoff_knobs.log
tar czf $OUT/results.tgz -C $OUT r && rm -rf $OUT/r
