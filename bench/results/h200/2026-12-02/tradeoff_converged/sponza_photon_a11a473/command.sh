. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
( time timeout $1 python3 -m rayvr bench tradeoff --scenes sponza --size 720x800 --poses 0 --repeat 10 --out $OUT/r/tradeoff_sponza ) > $OUT/r/tradeoff_sponza.log 2>&1; echo "tradeoff rc=$?"
tail -c 600 $OUT/r/tradeoff_sponza.log
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
