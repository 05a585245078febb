# bench with the round tiles' whole-frame fallback and the shared auto choice, then the suite serially (three thirds)
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 130 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras pinhole,distorted_chromatic --counts 1,4,16 --repeat 10 --out $OUT/r/vr_rounds > $OUT/r/vr_rounds.log 2>&1; echo "rounds rc=$?"
f=$OUT/r/vr_rounds/vr.md; sed -n '/^| config/,/^$/p' $f | cut -d'|' -f3-5,7,9,10,12,14; grep "^- shadows" $f; grep -A7 "^| target" $f
for h in 0 1 2; do ( timeout 440 python3 -m pytest -v --tb=short -p no:cacheprovider $(cat .gpu/third_$h.txt) > $OUT/r/suite_serial_$h.log 2>&1; echo "serial $h rc=$?" ) & done
wait
for h in 0 1 2; do tail -n 1 $OUT/r/suite_serial_$h.log; grep -E "(FAILED|ERROR)" $OUT/r/suite_serial_$h.log | head -5; done
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
