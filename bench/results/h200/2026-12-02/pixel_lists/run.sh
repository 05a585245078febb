# call D: per-pixel MSAA trace from the tile lists against the entries (default) on bench vr
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes
V="python3 -m rayvr bench vr --scenes default,sponza --poses 5 --configs shadows --repeat 25"
timeout 150 $V --counts 4,16 --cameras pinhole,distorted_chromatic --out $OUT/entries > $OUT/bench.log 2>&1; echo "entries rc=$?"
timeout 150 $V --counts 4,16 --cameras pinhole,distorted_chromatic --tile-lists 256 --out $OUT/lists256 >> $OUT/bench.log 2>&1; echo "lists256 rc=$?"
timeout 100 $V --counts 16 --cameras pinhole --tile-lists 1024 --out $OUT/lists1024 >> $OUT/bench.log 2>&1; echo "lists1024 rc=$?"
for d in entries lists256 lists1024; do grep -E "^\| shadows" $OUT/$d/vr.md; done
