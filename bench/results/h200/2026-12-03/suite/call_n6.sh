# next session, call A (~420 s): the suite with -n 6 ALONE, verbose (names in completion order), short tracebacks
. .gpu/setup.sh
mkdir -p $OUT/r
timeout 400 python3 -m pytest -n 6 -v --tb=short -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -n 1 $OUT/r/suite_n6.log
grep -E "(FAILED|ERROR)" $OUT/r/suite_n6.log | head -20
nvidia-smi -q -d PERFORMANCE | grep -iE "throttle|slowdown" | head -5
cp $OUT/device.txt $OUT/commit.txt $OUT/r/
