# call 3: the whole suite with -n 6 alone (call 2 ran it beside four serial quarters: starved, cut at 300 s)
. .gpu/setup.sh
mkdir -p $OUT/r
timeout 285 python3 -m pytest -n 6 -q --tb=short -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "n6 rc=$?"; tail -n 1 $OUT/r/suite_n6.log
grep -E "^(FAILED|ERROR)" $OUT/r/suite_n6.log | head -20
cp $OUT/device.txt $OUT/commit.txt $OUT/r/
