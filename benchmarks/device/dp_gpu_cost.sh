#!/usr/bin/env bash
# The paper preset's DP/DPES training step and action chunk on a GPU machine with no network
# (benchmarks/speed/dp_gpu_cost.py gpu), run from the repository root. The machine's python3 has
# torch; lerobot 0.4.4 and the packages it imports that the machine lacks travel installed in
# SITE, made here with
#   uv pip install --target .dpcarry/site --python-version 3.12 --python-platform \
#     x86_64-manylinux_2_28 --no-deps lerobot==0.4.4 diffusers==0.35.2 draccus==0.10.0 \
#     datasets==4.8.5 deepdiff==8.6.2 orderly-set==5.5.0 mergedeep==1.3.4 multiprocess==0.70.19 \
#     dill==0.4.1 pydantic==2.14.3 pydantic-core==2.50.4 pyserial==3.5 typing-inspection==0.4.5 \
#     huggingface-hub==0.35.3
# (diffusers' pipelines/ and modular_pipelines/ may be deleted to save space), and the env shapes
# in SHAPES, made here with `uv run python benchmarks/speed/dp_gpu_cost.py shapes --out ...`.
# Results go to $OUT/dp_gpu_cost.json (rewritten after every env and method) and $OUT/gpu.log.
set -uo pipefail
OUT=${OUT:?set OUT to the results folder}
SITE=${SITE:-.dpcarry/site}
SHAPES=${SHAPES:-.dpcarry/shapes.json}
export PYTHONPATH=$PWD/$SITE HF_HUB_OFFLINE=1 PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
python3 -c "import torch; print('torch', torch.__version__, torch.cuda.is_available())" || exit 1
t0=$(date +%s)
python3 benchmarks/speed/dp_gpu_cost.py gpu --shapes "$SHAPES" --out "$OUT/dp_gpu_cost.json" \
    --require-cuda --steps "${STEPS:-30}" --warmup 5 --chunks 10 2>&1 | tee "$OUT/gpu.log"
echo "total $(( $(date +%s) - t0 )) s"
