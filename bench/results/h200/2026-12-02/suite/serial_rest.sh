# call: the serial suite's remaining files (half 1 from test_raytrace.py, then half 2)
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
timeout 545 python3 -m pytest -v -p no:cacheprovider $(cat .gpu/serial_rest.txt) > $OUT/suite_serial_rest.log 2>&1; echo "rest rc=$?"; tail -2 $OUT/suite_serial_rest.log
grep -E "(FAILED|ERROR)" $OUT/suite_serial_rest.log | head -10; grep -cE "PASSED|SKIPPED" $OUT/suite_serial_rest.log
