# call E: the parallel MSAA merge, and the MSAA trace's workgroup size 64 / 128 / 256
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
for g in 64 128 256; do
  MSAA_GROUP=$g timeout 120 python3 .gpu/group_exp.py bench vr --scenes default,sponza --poses 5 --configs shadows --repeat 25 --counts 4,16 --cameras pinhole,distorted_chromatic --out $OUT/merge_g$g >> $OUT/bench.log 2>&1; echo "g$g rc=$?"
  grep -E "^\| shadows" $OUT/merge_g$g/vr.md | cut -d'|' -f4,6,12
done
timeout 150 python3 .gpu/denoise_prof.py $OUT/denoise_prof.json > $OUT/denoise.log 2>&1; echo "denoise rc=$?"; tail -8 $OUT/denoise.log
