#!/usr/bin/env bash
# Fill the ignored folders the device runs need, from the project root: .gl/ and .whl/ (the offline
# bundle), .gpu/ (these scripts, the shared scenes packed small, the commit, the suite's parts).
# Carry [".gl", ".whl", ".gpu"]: the device copies at most 64 MiB with the working tree, and the
# scenes unpacked (15 MB) with the embreex wheel (14 MB) and the tracked results pass it, so the
# scenes travel as .gpu/scenes.tar.xz (5 MB) and setup.sh unpacks them there.
# Usage: [OLD=COMMIT] tools/device/prepare.sh [PARTS]   (PARTS: serial suite processes, default 9)
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
parts=${1:-9}
ls .whl/embreex-* >/dev/null 2>&1 || bash ../shared/gpu/bundle-offline.sh tqdm==4.67.1 \
  pytest==8.3.4 pytest-xdist==3.6.1 execnet==2.1.1 iniconfig==2.0.0 pluggy==1.5.0 packaging==24.2 \
  flip-evaluator==1.7 embreex==4.4.0.post1
grep -qxF /.gpu/ .git/info/exclude || echo /.gpu/ >> .git/info/exclude
mkdir -p .gpu && rm -f .gpu/part_*.txt
cp tools/device/setup.sh tools/device/suite.sh tools/device/budget.sh tools/device/vr.sh .gpu/
# OLD=COMMIT: that commit's rayvr/ in .old/ with this tree's head poses (vr.sh times both on the same heads)
if [ -n "${OLD:-}" ]; then
  grep -qxF /.old/ .git/info/exclude || echo /.old/ >> .git/info/exclude
  rm -rf .old && mkdir .old && git archive "$OLD" rayvr | tar -x -C .old
  cp rayvr/bench/head_poses.py .old/rayvr/bench/ && git rev-parse --short "$OLD" > .old/commit.txt
fi
tar -C ../shared -cJf .gpu/scenes.tar.xz scenes
git rev-parse --short HEAD > .gpu/commit.txt
# test files dealt to the parts heaviest first (weight: test functions), each to the lightest part
for f in tests/test_*.py; do echo "$(grep -c '^def test_\|^    def test_' "$f") $f"; done | sort -rn |
  awk -v n="$parts" '{best=0; for (i=1; i<n; i++) if (w[i] < w[best]) best=i; w[best]+=$1+1;
                      printf "%s ", $2 >> sprintf(".gpu/part_%02d.txt", best)}'
du -sh .gl .whl .gpu $([ -d .old ] && echo .old)
