# The whole suite twice at once on one GPU: pytest -n 6, and serially in the parts prepare.sh
# dealt (each part's files one test after another, in its own process). Logs under $OUT/s,
# written as they go (a call cut short returns up to 8 of them) and packed as $OUT/s_PID.tgz.
. .gpu/setup.sh $OUT/s
export PYTEST_DISABLE_PLUGIN_AUTOLOAD=1
(timeout 560 python3 -m pytest -p xdist -n 6 -q -p no:cacheprovider tests > $OUT/s/suite_n6.log 2>&1
 echo "rc $?" >> $OUT/s/suite_n6.log) &
for part in .gpu/part_*.txt; do
  log=$OUT/s/suite_serial_$(basename $part .txt).log
  (timeout 560 python3 -m pytest -q -p no:cacheprovider $(cat $part) > $log 2>&1; echo "rc $?" >> $log) &
done
wait
for f in $OUT/s/suite_*.log; do echo "== $(basename $f)"; grep -E "passed|failed|error|^rc" $f | tail -2; done
