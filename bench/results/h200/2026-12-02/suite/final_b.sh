# call B: the whole suite serially
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
timeout ${1:-560} python3 -m pytest -q -p no:cacheprovider --durations=15 tests > $OUT/suite_serial.log 2>&1; echo "serial rc=$?"; tail -3 $OUT/suite_serial.log
grep -E "FAILED|ERROR" $OUT/suite_serial.log | head -10
