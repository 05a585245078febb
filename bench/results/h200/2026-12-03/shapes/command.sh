# call S: tile size, entry bound and block side by measurement (issue 22 item 4) on Sponza, then 8x shared vs apart
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
V="chosen:;t8:tile_size=8x8;t16:tile_size=16x16;e16:tile_entries=16;e64:tile_entries=64;b4:block_tiles=4;b16:block_tiles=16"
timeout 400 python3 -m rayvr bench vr --scenes sponza --poses 3 --configs shadows --cameras pinhole,distorted_chromatic,wide_210x130,dof_0.5m --counts 1,4,16 --variants "$V" --repeat 10 --out $OUT/r/vr_shapes > $OUT/r/vr_shapes.log 2>&1; echo "shapes rc=$?"
tr '\r' '\n' < $OUT/r/vr_shapes.log | grep "frame median" | cut -c1-110 | tail -n 90
timeout 60 python3 -m rayvr bench vr --scenes sponza --poses 3 --configs shadows --cameras distorted_chromatic --counts 8 --variants "shared:share_channel_shading=on;apart:share_channel_shading=off" --repeat 10 --out $OUT/r/vr_shared8 > $OUT/r/vr_shared8.log 2>&1; echo "shared8 rc=$?"
tr '\r' '\n' < $OUT/r/vr_shared8.log | grep "frame median" | cut -c1-110
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
