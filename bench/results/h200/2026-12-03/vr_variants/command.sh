# call 1: issue 22's tests on the H200, then the primary-visibility variants of bench vr
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 110 python3 -m pytest -n 8 -q -p no:cacheprovider tests/test_tile_lists.py tests/test_block_culling.py tests/test_shared_channels.py tests/test_msaa_rounds.py > $OUT/r/smoke.log 2>&1; echo "smoke rc=$?"; tail -n 2 $OUT/r/smoke.log
grep -E "^(FAILED|ERROR)" $OUT/r/smoke.log | head -10
V="perray:tile_culling=off;entries:tile_culling=on,tile_lists=0,block_culling=off;lists:tile_lists=256,block_culling=off;blocks:block_culling=on,tile_lists=256;blocks_entries:block_culling=on,tile_lists=0"
timeout $1 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras pinhole,distorted_chromatic,foveated,wide_210x130,dof_0.5m --counts 1,4,16,32 --variants "$V" --repeat 10 --out $OUT/r/vr_variants > $OUT/r/vr_variants.log 2>&1; echo "vr rc=$?"
grep -E "frame median" $OUT/r/vr_variants.log | tr '\r' '\n' | grep "frame median" | cut -c1-120 | tail -n 100
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
