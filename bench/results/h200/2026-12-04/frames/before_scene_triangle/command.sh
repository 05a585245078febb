. .gpu/setup.sh
mkdir -p $OUT/f $OUT/l
python3 .gpu/frames.py $OUT/f default=bvh4,bvh2,bvh4 cw=bvh4,cwbvh,cwbvh 2>&1 | tee $OUT/f/frames.log | grep -v "^ "
python3 .gpu/lmem_scan.py $OUT/l > $OUT/l/scan.log 2>&1; grep -v "\[\] ops 0" $OUT/l/scan.log | tail -40
cd $OUT && tar czf results.tgz f l && rm -rf f l
