# next session, call F (~400 s): bench vr with round_passes (where an MSAA round's time goes) and the
# longer warm-ups, plus the room's per-ray first cells that the short warm-up inflated
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
mkdir -p $OUT/r
timeout 200 python3 -m rayvr bench vr --scenes sponza,default --poses 3 --configs shadows --cameras pinhole,distorted_chromatic --counts 1,4,16 --repeat 10 --out $OUT/r/vr_rounds > $OUT/r/vr_rounds.log 2>&1; echo "rounds rc=$?"
timeout 90 python3 -m rayvr bench vr --scenes default --poses 3 --configs shadows --cameras pinhole,foveated,wide_210x130,dof_0.5m --counts 1 --variants "perray:tile_culling=off" --repeat 10 --out $OUT/r/vr_warmup > $OUT/r/vr_warmup.log 2>&1; echo "warmup rc=$?"
timeout 90 python3 -m rayvr bench vr --scenes sponza --poses 3 --configs shadows --cameras distorted_chromatic --counts 16 --variants "shared:;apart:share_channel_shading=off" --repeat 10 --out $OUT/r/vr_shared16 > $OUT/r/vr_shared16.log 2>&1; echo "shared16 rc=$?"
python3 - <<'PY'
import json, os
rows = json.load(open(os.environ["OUT"] + "/r/vr_rounds/vr.json"))
rows = rows["rows"] if isinstance(rows, dict) else rows
for r in rows:
    if r["msaa"] > 1 and r["pose"]["index"] == 0:
        print(r["scene"], r["camera"], r["msaa"], {k: v for k, v in r.get("round_passes", {}).items()})
PY
cp $OUT/device.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
