# next session, call B (~560 s): the suite serially as three thirds side by side (no -n 6 beside them)
. .gpu/setup.sh
for h in 0 1 2; do ( timeout 540 python3 -m pytest -v --tb=short -p no:cacheprovider $(cat .gpu/third_$h.txt) > $OUT/suite_serial_$h.log 2>&1; echo "serial $h rc=$?" ) & done
wait
for h in 0 1 2; do tail -n 1 $OUT/suite_serial_$h.log; grep -E "(FAILED|ERROR)" $OUT/suite_serial_$h.log | head -5; done
