"""Registration of the LimbRepositioning3D ids (string entry points only: nothing here imports
pybullet)."""

from __future__ import annotations

from kinder_core.registration import register_family

FAMILY = "LimbRepositioning3D"
ENTRY_POINT = "kinder_garden3d.limb3d.env:LimbRepositioning3DEnv"
#: The scenes, and the limbs of each.
SCENES = ("isolated", "human", "wheelchair", "bed")
LIMB_VARIANTS = ("left-arm", "right-arm", "left-leg", "right-leg")
#: Upstream registers no step limit; 2400 steps are 10 s of simulated time at 240 Hz.
MAX_EPISODE_STEPS = 2400


def register_limb3d() -> list[str]:
    """Register the LimbRepositioning3D ids (``<scene>-<side>-<limb>``); returns them."""
    variants = {f"{s}-{limb}": {"variant": f"{s}-{limb}"} for s in SCENES for limb in LIMB_VARIANTS}
    return register_family(FAMILY, ENTRY_POINT, variants, max_episode_steps=MAX_EPISODE_STEPS)
