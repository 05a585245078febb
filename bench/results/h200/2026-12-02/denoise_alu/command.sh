# session 11 call D: bench tradeoff at 2x720x800 (fixed view + 1 head pose) on both scenes; the denoiser candidate; the depth-free capture read-back
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
timeout 60 python3 -m rayvr capture --size 1440x1600 --frames 4 --out /tmp/warm -q > /dev/null 2>&1
for s in default sponza; do
( time timeout $1 python3 -m rayvr bench tradeoff --scenes $s --size 720x800 --poses 1 --repeat 25 --out $OUT/r/tradeoff_$s ) > $OUT/r/tradeoff_$s.log 2>&1; echo "tradeoff $s rc=$?"; tail -c 600 $OUT/r/tradeoff_$s.log | tr '\r' '\n' | tail -3 | cut -c1-150
done
if [ "$2" = all ]; then
timeout 60 python3 .gpu/denoise_prof.py $OUT/r/denoise_main.json > $OUT/r/denoise_main.log 2>&1; echo "denoise main rc=$?"; tail -8 $OUT/r/denoise_main.log | cut -c1-200
( time timeout 40 python3 -m rayvr capture --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 48 --out /tmp/cap_room -q ) > $OUT/r/capture_room_main.log 2>&1; echo "capture main rc=$?"; tail -4 $OUT/r/capture_room_main.log
cp -r .gpu/alu/rayvr/. rayvr/; cp -r .gpu/nodepth/rayvr/. rayvr/
timeout 60 python3 .gpu/denoise_prof.py $OUT/r/denoise_alu.json > $OUT/r/denoise_alu.log 2>&1; echo "denoise alu rc=$?"; tail -8 $OUT/r/denoise_alu.log | cut -c1-200
( time timeout 40 python3 -m rayvr capture --materials rayvr/assets/default_room.toml --size 1440x1600 --frames 48 --out /tmp/cap_room2 -q ) > $OUT/r/capture_room_nodepth.log 2>&1; echo "capture nodepth rc=$?"; tail -4 $OUT/r/capture_room_nodepth.log
timeout 100 python3 -m pytest -n 6 -q -p no:cacheprovider tests/test_denoise*.py tests/test_readback.py tests/test_capture*.py > $OUT/r/exp_tests.log 2>&1; echo "exp tests rc=$?"; tail -3 $OUT/r/exp_tests.log
fi
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
