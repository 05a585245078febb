. .gpu/setup.sh
mkdir -p $OUT/f $OUT/d
python3 .gpu/frames.py $OUT/f default=bvh4,bvh2,bvh4 rf=bvh4,bvh2,cwbvh 2>&1 | tee $OUT/f/frames.log | grep SUMMARY
for v in fold_b3 old old_b3; do
  case $v in
    fold_b3) cp .gpu/dn_new.comp rayvr/glsl/post/denoise.comp; cp .gpu/dn_new.py rayvr/frame/passes/denoise.py;;
    old) cp .gpu/dn_old/post/denoise.comp rayvr/glsl/post/denoise.comp; cp .gpu/dn_old/denoise.py rayvr/frame/passes/denoise.py;;
    old_b3) cp .gpu/dn_oldb3/post/denoise.comp rayvr/glsl/post/denoise.comp; cp .gpu/dn_oldb3/denoise.py rayvr/frame/passes/denoise.py;;
  esac
  mkdir -p $OUT/d/$v
  SCENES=default CONFIGS=room STAGES=denoise SETTINGS='{"denoise": true}' POSES=4 python3 .gpu/frames.py $OUT/d/$v default= > $OUT/d/$v/frames.log 2>&1
  python3 -c "
import json,sys; rows=json.load(open('$OUT/d/$v/frames.json'))
print('$v', 'denoise pass', [round(r['pass_ms']['denoise'],3) for r in rows], 'kernels', [round(sum(r['kernel_ms'].values()),3) for r in rows])"
done
cd $OUT && tar czf results.tgz f d && rm -rf f d
