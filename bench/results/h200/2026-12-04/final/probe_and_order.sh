. .gpu/setup.sh
mkdir -p $OUT/r
git log --oneline -1 2>/dev/null > $OUT/r/commit.txt
timeout 420 python3 -m pytest -n 6 -q -p no:cacheprovider tests > $OUT/r/suite_n6.log 2>&1; echo "rc $?" >> $OUT/r/suite_n6.log
tail -15 $OUT/r/suite_n6.log
SCENES=sponza KINDS=glossy_0.1,glossy_0.6,reflect LAYOUTS=bvh2,bvh4,cwbvh timeout 150 python3 .gpu/cw_probe.py $OUT/r/probe_sponza 2>&1 | grep -v "^ \|bytes" | tee $OUT/r/probe_sponza.log
rm -f $OUT/r/probe_sponza/*.bin $OUT/r/probe_sponza/*.nvasm
for o in none morton; do for w in "" 67108864; do
  SCENES=sponza CONFIGS=path4 POSES=1 SETTINGS="{\"ray_order\": \"$o\"}" WAVE_BYTES=$w timeout 60 python3 .gpu/frames.py $OUT/r/order_${o}_${w:-default} default= > /dev/null 2>&1
  python3 -c "import json; r=json.load(open('$OUT/r/order_${o}_${w:-default}/frames.json'))[0]; print('$o', '${w:-default}', round(r['frame_ms'],2), {k: round(v,2) for k,v in r['kernel_ms'].items()})"
done; done
cd $OUT && tar czf results.tgz r && rm -rf r
