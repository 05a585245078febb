. .gpu/setup.sh
mkdir -p $OUT/s
for i in 0 1 2 3; do
  (PYTEST_DISABLE_PLUGIN_AUTOLOAD=1 timeout 560 python3 -m pytest -q -p no:cacheprovider $(cat .gpu/quarter_$i.txt) > $OUT/s/suite_serial_$i.log 2>&1; echo "rc $?" >> $OUT/s/suite_serial_$i.log) &
done
wait
for i in 0 1 2 3; do echo "== quarter $i"; grep -E "passed|failed|error|^rc" $OUT/s/suite_serial_$i.log | tail -3; done
cd $OUT && tar czf results.tgz s && rm -rf s
