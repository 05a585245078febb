# call: issue 24 capture figures with the GIL-free PNG encoder; writers sweep; views profiled
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
S=.shared/scenes/sponza_dabrovic/sponza.obj
run() { n=$1; shift; ( time timeout 60 python3 -m rayvr capture "$@" --timings ) > $OUT/r/$n.log 2>&1; echo "$n rc=$?"; tr '\r' '\n' < $OUT/r/$n.log | grep -E "frame/s|frames/s|it/s|real" | tail -2 | cut -c1-200; }
R="--size 1440x1600 --frames 48"
run room_wdefault $R --out /tmp/c1
run room_w8 $R --writers 8 --out /tmp/c2
run room_w4 $R --writers 4 --out /tmp/c3
run room_w1 $R --writers 1 --out /tmp/c4
run sponza_wdefault $S $R --out /tmp/c5
run views_wdefault --views sphere:256 --eye left --size 800x800 --out /tmp/c6
run views_w1 --views sphere:256 --eye left --size 800x800 --writers 1 --out /tmp/c7
for d in c1 c2 c3 c4 c5 c6 c7; do cp /tmp/$d/frame_timings.json $OUT/r/$d.timings.json 2>/dev/null; done
timeout 60 python3 -m cProfile -o $OUT/r/views.prof -m rayvr capture -q --views sphere:128 --eye left --size 800x800 --out /tmp/c8 > $OUT/r/views_prof.log 2>&1; echo "prof rc=$?"
python3 -c "import pstats; s=pstats.Stats('$OUT/r/views.prof'); s.sort_stats('tottime').print_stats(40)" > $OUT/r/views_prof_tottime.txt 2>&1
python3 -c "import pstats; s=pstats.Stats('$OUT/r/views.prof'); s.sort_stats('cumulative').print_stats(60)" > $OUT/r/views_prof_cum.txt 2>&1
head -50 $OUT/r/views_prof_tottime.txt | tail -42 | cut -c1-150
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
