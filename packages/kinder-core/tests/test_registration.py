import gymnasium
import pytest

import kinder_core
from kinder_core.registration import FAMILY_SOURCES, make_id, register_family


def test_static_family_table_has_the_25_paper_families_and_the_upstream_extras() -> None:
    cats = [s.category for s in FAMILY_SOURCES.values()]
    assert len(FAMILY_SOURCES) == 31
    assert [cats.count(c) for c in ("Kinematic2D", "Dynamic2D", "Kinematic3D", "Dynamic3D")] == [
        6,
        4,
        8,
        13,
    ]
    assert kinder_core.families("Dynamic2D") == [
        "DynObstruction2D",
        "DynPushT2D",
        "DynPushPullHook2D",
        "DynScoopPour2D",
    ]


def test_ids() -> None:
    assert make_id("Motion2D", "p3") == "kinder/Motion2D-p3-v0"
    assert make_id("BaseMotion3D") == "kinder/BaseMotion3D-v0"


def test_unknown_family_suggests_close_matches() -> None:
    with pytest.raises(ValueError, match=r"did you mean \['Motion2D'"):
        kinder_core.make("kinder/Motoin2D-p0-v0")
    with pytest.raises(ValueError, match="not a KinDER id"):
        kinder_core.make("CartPole-v1")
    with pytest.raises(ValueError, match="Unknown category"):
        kinder_core.list_envs("Kinematic4D")


def test_register_family_validates_and_is_idempotent() -> None:
    with pytest.raises(ValueError, match="Unknown family"):
        register_family("Nope2D", "x:Y", {"": {}}, 10)
    with pytest.raises(ValueError, match="module:Class"):
        register_family("Motion2D", "nocolon", {"": {}}, 10)
    ids = register_family("Dynamo3D", "toy_env:ToyReach", {"zz9": {"num_pebbles": 1}}, 7)
    assert ids == ["kinder/Dynamo3D-zz9-v0"]
    assert register_family("Dynamo3D", "toy_env:ToyReach", {"zz9": {}}, 7) == ids
    spec = gymnasium.spec(ids[0])
    assert spec.max_episode_steps == 7 and spec.kwargs["num_pebbles"] == 1
    env = kinder_core.make(ids[0])
    assert env.reset(seed=0)[0].shape == (8,)
    gymnasium.registry.pop(ids[0])
    kinder_core.registration._REGISTERED["Dynamo3D"].variants.pop("zz9")


def test_variant_steps_give_one_variant_its_own_limit() -> None:
    variants = {"zz7": {"num_pebbles": 1}, "zz8": {"num_pebbles": 2}}
    with pytest.raises(ValueError, match="not a variant of Dynamo3D"):
        register_family("Dynamo3D", "toy_env:ToyReach", variants, 7, {"zz6": 9})
    with pytest.raises(ValueError, match="must be positive"):
        register_family("Dynamo3D", "toy_env:ToyReach", variants, 7, {"zz8": 0})
    ids = register_family("Dynamo3D", "toy_env:ToyReach", variants, 7, {"zz8": 30})
    assert [gymnasium.spec(i).max_episode_steps for i in ids] == [7, 30]
    info = kinder_core.registration._REGISTERED["Dynamo3D"]
    assert info.step_limit("zz8") == 30 and info.step_limit("zz7") == info.max_episode_steps
    for variant, env_id in zip(variants, ids, strict=True):
        gymnasium.registry.pop(env_id)
        info.variants.pop(variant)
        info.variant_steps.pop(variant, None)


def test_module_prefixed_make_and_register_envs_work_for_garden2d() -> None:
    # gymnasium's documented third-party pattern: "module:id" imports the module first.
    import kinder_garden2d

    gymnasium.register_envs(kinder_garden2d)
    ids = kinder_core.list_envs("Kinematic2D")
    if not ids:
        pytest.skip("kinder-garden2d registers no Kinematic2D envs yet")
    env = gymnasium.make(f"kinder_garden2d:{ids[0]}")
    env.reset(seed=0)
