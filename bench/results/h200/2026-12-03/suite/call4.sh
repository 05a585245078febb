# call 4: why the suite fails on the H200: the first failing tests of call 2's serial quarters, alone
. .gpu/setup.sh
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=memory.used,utilization.gpu --format=csv
timeout 70 python3 -m pytest -x -q --tb=short -p no:cacheprovider --durations=5 "tests/test_frame_budget.py::test_reference_never_shares_a_variants_seed" tests/test_gbuffer.py::test_sphere_depth_and_normals_match_analytic "tests/test_emission.py::test_the_gltf_area_light_lights_the_floor_as_the_closed_form" tests/test_dof.py 2>&1 | grep -v Warning | tail -n 60
nvidia-smi --query-gpu=memory.used,utilization.gpu --format=csv
