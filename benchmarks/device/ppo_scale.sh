#!/usr/bin/env bash
# The batched-env speed table and the PPO scale study (benchmarks/experiments/ppo_scale.py) on a GPU machine
# with 16 cores and no network, run from the repository root with the wheels the machine lacks in
# .whl/ (gymnasium, farama-notifications, pymunk, cffi, pycparser, ompl, stable-baselines3; the
# machine's own python3 has torch and numpy). Results go to $OUT:
#   vector_speed_device.json  batched Kinematic2D steps/s, one core (core 15), nothing else running
#   <env>.tgz                 each PPO run's config, progress, log and kept checkpoints
# WALL is each PPO run's training time limit in seconds (ppo_scale.py's --max-wall-s).
set -uo pipefail
OUT=${OUT:?set OUT to the results folder}
WALL=${WALL:-380}
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 1
PYTHONPATH=/tmp/site:$(ls -d "$PWD"/packages/*/src | paste -sd:)
export PYTHONPATH SDL_VIDEODRIVER=dummy OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 PYTHONUNBUFFERED=1
nproc; lscpu | grep -m1 "Model name"; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
python3 -c "import torch, kinder_bench.baselines.rl.train as t; print('torch', torch.__version__, torch.cuda.is_available())" || exit 1
t0=$(date +%s)
taskset -c 15 python3 benchmarks/speed/vector_speed.py --no-upstream --seconds 1 --single-steps 5000 \
    --out "$OUT/vector_speed_device.json" > "$OUT/vector_speed.log" 2>&1
echo "speed table: rc $? in $(( $(date +%s) - t0 )) s"; tail -3 "$OUT/vector_speed.log"
python3 benchmarks/experiments/ppo_scale.py train --out runs/ppo_scale --device cuda --max-wall-s "$WALL" \
    --jobs 15 2>&1 | tail -20
for f in runs/ppo_scale/train/*/seed0/progress.csv; do echo "$f"; tail -2 "$f" | cut -c1-80; done
grep -h -m1 -i "error\|Traceback" runs/ppo_scale/train/*/seed*/train.log | head -5
python3 benchmarks/experiments/ppo_scale.py pack --out runs/ppo_scale --dest "$OUT"
echo "total $(( $(date +%s) - t0 )) s"
