"""The diffusion policies' configurations as data: lerobot ``DiffusionConfig`` fields per preset.

A module of plain data with no imports beyond the standard library, so that a measurement on a
machine without this project installed (``benchmarks/speed/dp_gpu_cost.py`` on a GPU machine) can
load the exact configuration by file path. :mod:`kinder_bench.baselines.diffusion` documents the
presets and the deviations from the paper.
"""

from __future__ import annotations

from typing import Any

METHODS = ("dp", "dpes")
PRESETS = ("paper", "cpu")

#: Fields of lerobot's ``DiffusionConfig`` set by each preset.
PRESET_FIELDS: dict[str, dict[str, Any]] = {
    "paper": {
        "down_dims": (256, 512, 1024),
        "diffusion_step_embed_dim": 128,
        "resize_shape": None,
    },
    "cpu": {
        "down_dims": (16, 32, 64),
        "diffusion_step_embed_dim": 32,
        "resize_shape": (64, 64),
    },
}
PRESET_BATCH = {"paper": 64, "cpu": 16}

#: The paper's training budget: up to 5001 epochs over an env's demonstrations (appendix).
PAPER_EPOCHS = 5001

#: Fields shared by both presets (the paper's settings).
COMMON_FIELDS: dict[str, Any] = {
    "n_obs_steps": 2,
    "horizon": 16,
    "n_action_steps": 8,
    "drop_n_last_frames": 7,
    "kernel_size": 5,
    "n_groups": 8,
    "use_film_scale_modulation": True,
    "vision_backbone": "resnet18",
    "pretrained_backbone_weights": None,
    "use_group_norm": True,
    "crop_shape": None,
    "crop_ratio": 1.0,
    "use_separate_rgb_encoder_per_camera": True,
    "noise_scheduler_type": "DDIM",
    "num_train_timesteps": 100,
    "num_inference_steps": 16,
    "beta_schedule": "squaredcos_cap_v2",
    "prediction_type": "epsilon",
    "clip_sample": True,
    "optimizer_lr": 1e-4,
    "optimizer_betas": (0.95, 0.999),
    "optimizer_weight_decay": 1e-6,
    "scheduler_warmup_steps": 500,
    "push_to_hub": False,
}
