. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
( time timeout 270 python3 -m rayvr bench tradeoff --scenes sponza --size 720x800 --poses 1 --repeat 10 --out $OUT/r/tradeoff_sponza_poses ) > $OUT/r/tradeoff_sponza_poses.log 2>&1; echo "tradeoff rc=$?"
( time timeout 90 python3 -m rayvr bench rays --scenes sponza,default --ray-order none,morton --persistent off,on --out $OUT/r/rays_order ) > $OUT/r/rays_order.log 2>&1; echo "rays rc=$?"
tail -3 $OUT/r/rays_order.log
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
