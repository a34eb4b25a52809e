import gymnasium
import pytest

TOY_IDS = {
    "kinder/ToyReach-v0": "toy_env:ToyReach",
    "kinder/LeakyToyReach-v0": "toy_env:LeakyToyReach",
}
for _id, _ep in TOY_IDS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(
            id=_id,
            entry_point="kinder_core.registration:make_box_env",
            kwargs={"env_entry_point": _ep},
            max_episode_steps=50,
        )


@pytest.fixture
def toy_id() -> str:
    return "kinder/ToyReach-v0"
