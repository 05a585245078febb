# call 2: the fix's tests, bench vr with the measured choices (nothing else running), then the whole
# suite twice at once: with -n 6, and serially as four quarters (each one process) side by side
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 45 python3 -m pytest -n 8 -q -p no:cacheprovider tests/test_shared_channels.py tests/test_tile_lists.py tests/test_block_culling.py > $OUT/r/fixed.log 2>&1; echo "fixed rc=$?"; tail -n 1 $OUT/r/fixed.log; grep -E "^(FAILED|ERROR)" $OUT/r/fixed.log | head
B="python3 -m rayvr bench vr --scenes sponza,default --repeat 10"
timeout 100 $B --poses 5 --configs shadows,room --cameras pinhole,distorted_chromatic --counts 1,4,16,32 --out $OUT/r/vr > $OUT/r/vr.log 2>&1; echo "vr rc=$?"
timeout 35 $B --poses 5 --configs shadows --cameras foveated,wide_210x130 --counts 1,4 --out $OUT/r/vr_models > $OUT/r/vr_models.log 2>&1; echo "vr models rc=$?"
timeout 30 $B --poses 3 --pose-seed 7 --configs shadows --cameras pinhole,distorted_chromatic --counts 1,4,16 --out $OUT/r/vr_seed7 > $OUT/r/vr_seed7.log 2>&1; echo "vr seed7 rc=$?"
( timeout 300 python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?" ) &
for h in 0 1 2 3; do ( timeout 300 python3 -m pytest -v -p no:cacheprovider --durations=10 $(cat .gpu/serial_$h.txt) > $OUT/r/suite_serial_$h.log 2>&1; echo "serial $h rc=$?" ) & done
wait
for f in $OUT/r/suite_*.log; do echo "$f: $(tail -n 1 $f)"; grep -E "^(FAILED|ERROR)|(FAILED|ERROR)$" $f | head -5; done
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
