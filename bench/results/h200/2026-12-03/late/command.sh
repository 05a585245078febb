# next session, call C (~500 s): the room's missing variant rows (block beams with entries), then bench vr's targets
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
V="perray:tile_culling=off;entries:tile_culling=on,block_culling=off;blocks_entries:block_culling=on,tile_lists=0"
timeout 200 python3 -m rayvr bench vr --scenes default --poses 3 --configs shadows --cameras pinhole,distorted_chromatic,foveated,wide_210x130,dof_0.5m --counts 1,4,16,32 --variants "$V" --repeat 10 --out $OUT/r/vr_variants_room > $OUT/r/vr_variants_room.log 2>&1; echo "variants rc=$?"
timeout 120 python3 -m rayvr bench vr --scenes sponza,default --poses 5 --configs shadows,room --cameras pinhole,distorted_chromatic --counts 1,4,16,32 --repeat 10 --out $OUT/r/vr > $OUT/r/vr.log 2>&1; echo "vr rc=$?"
timeout 60 python3 -m rayvr bench vr --scenes sponza,default --poses 5 --configs shadows --cameras foveated,wide_210x130,dof_0.5m --counts 1,4,16 --repeat 10 --out $OUT/r/vr_models > $OUT/r/vr_models.log 2>&1; echo "models rc=$?"
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
