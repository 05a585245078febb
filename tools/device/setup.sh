# Sourced first by every device command (tools/device/README.md) with its results folder:
# `. .gpu/setup.sh $OUT/r`. The GL loader, the wheels, the shared scenes as ../shared, the NVIDIA
# EGL vendor; the folder gets device.txt (GPU, driver, clock) and commit.txt. On exit the folder
# is packed as $OUT/FOLDER_PID.tgz and removed: a call returns at most 8 files from $OUT (on
# 2026-12-06 a budget run's 15 files were left on the machine).
for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
export PYTHONPATH=/tmp/site:$PWD
mkdir -p .shared && tar -C .shared -xJf .gpu/scenes.tar.xz
[ -e ../shared ] || ln -s "$PWD/.shared" ../shared
export RAYVR_SCENES=$PWD/.shared/scenes RAYVR_COMMIT=$(cat .gpu/commit.txt)
vendor=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
[ -f $vendor ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$vendor
mkdir -p $1 && cp .gpu/commit.txt $1/commit.txt
trap "tar czf $OUT/$(basename $1)_$$.tgz -C $(dirname $1) $(basename $1) && rm -rf $1" EXIT
nvidia-smi --query-gpu=name,driver_version,clocks.sm --format=csv,noheader > $1/device.txt
