. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
( time timeout $1 python3 -m rayvr bench rays --scenes sponza,default --layouts bvh2,bvh4 --repeat 20 \
   --ray-order none,morton --persistent off,on --out $OUT/r/rays_order ) > $OUT/r/rays_order.log 2>&1; echo "rc=$?"
tail -c 3000 $OUT/r/rays_order.log
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
