# call F: one invocation per shadow ray (bench vr 1x, and the room's own view per stage)
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
mkdir -p $OUT/r
timeout 120 python3 -m rayvr bench vr --scenes default,sponza --poses 5 --configs shadows,room --counts 1 --cameras pinhole,distorted_chromatic --repeat 25 --out $OUT/r/vr > $OUT/r/bench.log 2>&1; echo "vr rc=$?"
grep -E "^\| (shadows|room)" $OUT/r/vr/vr.md | cut -d'|' -f2,4,8,9,13
timeout 100 python3 .gpu/denoise_prof.py $OUT/r/denoise_prof.json > $OUT/r/denoise.log 2>&1; echo "prof rc=$?"
python3 -c "
import json; d=json.load(open('$OUT/r/denoise_prof.json'))
for r in d['rows']:
    print(r['pose'], r['denoise'], {k: round(v,3) for k,v in r['ms'].items() if k.startswith('rt_')})"
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
