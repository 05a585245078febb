# both halves of the suite, each serially in its own process, side by side
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
( timeout $1 python3 -m pytest -v -p no:cacheprovider --durations=30 $(cat .gpu/serial_a.txt) > $OUT/suite_serial_a.log 2>&1; echo "a rc=$?" ) &
( timeout $1 python3 -m pytest -v -p no:cacheprovider --durations=30 $(cat .gpu/serial_b.txt) > $OUT/suite_serial_b.log 2>&1; echo "b rc=$?" ) &
wait
for h in a b; do tail -n 1 $OUT/suite_serial_$h.log; grep -E "(FAILED|ERROR)" $OUT/suite_serial_$h.log | head -10; done
