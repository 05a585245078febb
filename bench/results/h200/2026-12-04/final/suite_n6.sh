. .gpu/setup.sh
mkdir -p $OUT/r
export PYTEST_DISABLE_PLUGIN_AUTOLOAD=1
timeout 450 python3 -m pytest -p xdist -n 6 -q -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "rc $?" >> $OUT/r/suite_n6.log
tail -12 $OUT/r/suite_n6.log
cd $OUT && tar czf results.tgz r && rm -rf r
