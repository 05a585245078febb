# session 11 call B/C: bench budget at 2x1440x1600 with the frame-knob grid, one scene ($1), fixed view + 1 head pose
. .gpu/setup.sh
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
mkdir -p $OUT/r
G="stereo=dual,reuse;spp=1,4;denoise=off,on;msaa=1,4"
timeout 60 python3 -m rayvr capture --size 1440x1600 --frames 4 --out /tmp/warm -q > /dev/null 2>&1
( time timeout $2 python3 -m rayvr bench budget --scenes $1 --poses 1 --repeat 25 --frame-knobs "$G" --out $OUT/r/budget_$1 ) > $OUT/r/budget_$1.log 2>&1; echo "budget $1 rc=$?"
tr '\r' '\n' < $OUT/r/budget_$1.log | grep -v "it/s\|effect/s\|s/effect\|variant/s\|s/variant" | tail -25 | cut -c1-200
cp $OUT/device.txt $OUT/commit.txt $OUT/r/; tar czf $OUT/results.tgz -C $OUT r
