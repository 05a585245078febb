"""Screen-space tracers only the benchmarks run (`rayvr bench ssrt`): the DDA baseline (dda.py) and
the Hi-Z min-max pyramid (hiz.py), measured against the renderer's quadtree (rayvr/accel/quadtree.py)."""
