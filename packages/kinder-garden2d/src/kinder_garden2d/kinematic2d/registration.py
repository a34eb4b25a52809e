"""Registration of the Kinematic2D ids (string entry points only; importing this is cheap)."""

from kinder_core.registration import register_family

_MODULE = "kinder_garden2d.kinematic2d"

# Step budget of every Kinematic2D id: the paper's bilevel-planning evaluation runs episodes of up
# to max_eval_steps=3000 and asserts that the env never truncates, so the registered TimeLimit
# must not be shorter. Learners wanting shorter episodes pass max_episode_steps to make().
MAX_EPISODE_STEPS = 3000

# Family → (entry point, max_episode_steps, {variant: constructor kwargs}).
FAMILIES: dict[str, tuple[str, int, dict[str, dict[str, object]]]] = {
    "Motion2D": (
        f"{_MODULE}.motion2d:Motion2DEnv",
        MAX_EPISODE_STEPS,
        {f"p{n}": {"num_passages": n} for n in range(6)},
    ),
    "Obstruction2D": (
        f"{_MODULE}.obstruction2d:Obstruction2DEnv",
        MAX_EPISODE_STEPS,
        {f"o{n}": {"num_obstructions": n} for n in range(5)},
    ),
    "ClutteredRetrieval2D": (
        f"{_MODULE}.clutteredretrieval2d:ClutteredRetrieval2DEnv",
        MAX_EPISODE_STEPS,
        {f"o{n}": {"num_obstructions": n} for n in (1, 10, 25)},
    ),
    "ClutteredStorage2D": (
        f"{_MODULE}.clutteredstorage2d:ClutteredStorage2DEnv",
        MAX_EPISODE_STEPS,
        {f"b{n}": {"num_blocks": n} for n in (1, 3, 7, 15)},
    ),
    "StickButton2D": (
        f"{_MODULE}.stickbutton2d:StickButton2DEnv",
        MAX_EPISODE_STEPS,
        {f"b{n}": {"num_buttons": n} for n in (1, 2, 3, 5, 10)},
    ),
    "PushPullHook2D": (f"{_MODULE}.pushpullhook2d:PushPullHook2DEnv", MAX_EPISODE_STEPS, {"": {}}),
}


# Every Kinematic2D id's native vector env (batched numpy, bit-exact with the single env).
VECTOR_ENTRY_POINT = f"{_MODULE}.batched.vector_env:Kinematic2DVectorEnv"


def register_kinematic2d() -> list[str]:
    """Register every Kinematic2D id with gymnasium; returns the ids."""
    ids: list[str] = []
    for family, (entry_point, max_steps, variants) in FAMILIES.items():
        ids += register_family(
            family, entry_point, variants, max_steps, vector_entry_point=VECTOR_ENTRY_POINT
        )
    return ids
