# call: the suite with -n 6 at HEAD
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
timeout 230 python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -2 $OUT/suite_n6.log
grep -E "^(FAILED|ERROR)" $OUT/suite_n6.log | head -10
