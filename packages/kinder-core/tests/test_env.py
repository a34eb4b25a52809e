import pickle

import gymnasium
import numpy as np
import pytest
from toy_env import ToyReach

import kinder_core
from kinder_core.testing import CHECKS, check_kinder_env


def test_toy_env_passes_the_test_kit(toy_id: str) -> None:
    check_kinder_env(toy_id)


@pytest.mark.parametrize(
    "check", ["set_state_determinism", "transition", "pickle", "gymnasium_checker"]
)
def test_test_kit_catches_hidden_state(check: str) -> None:
    with pytest.raises(AssertionError):
        CHECKS[check]("kinder/LeakyToyReach-v0")


def test_reset_sparse_reward_and_termination() -> None:
    env = ToyReach()
    s, info = env.reset(seed=3)
    assert info == {"success": False}
    target = s.get_object_from_name("target")
    robot = s.get_object_from_name("robot")
    near = s.copy()
    near[robot][:2] = near[target][:2] + 0.05
    env.set_state(near)
    _, reward, terminated, truncated, info = env.step(np.zeros(2))
    assert (reward, terminated, truncated, info) == (-1.0, True, False, {"success": True})
    far = s.copy()
    far[robot][:2] = far[target][:2] + 0.5
    _, reward, terminated = env.transition(far, np.zeros(2))
    assert (reward, terminated) == (-1.0, False)


def test_reset_from_init_state_as_state_or_vector() -> None:
    env = ToyReach()
    s, _ = env.reset(seed=0)
    s2 = s.copy()
    s2.data += 0.01
    got, _ = env.reset(options={"init_state": s2})
    assert got == s2
    got, _ = env.reset(options={"init_state": env.box_space.vectorize(s2)})
    assert got == s2
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"bogus": 1})
    with pytest.raises(ValueError, match="expects"):
        env.reset(options={"init_state": np.zeros(3)})
    with pytest.raises(ValueError, match="objects"):
        env.set_state(ToyReach(num_pebbles=5).reset(seed=0)[0])


def test_same_seed_same_episode_and_rng_untouched_by_exemplar() -> None:
    a, b = ToyReach(), ToyReach()
    _ = b.box_space  # builds the exemplar from a private RNG
    assert a.reset(seed=11)[0] == b.reset(seed=11)[0]
    assert a.reset()[0] == b.reset()[0]


def test_goals_reached_defaults_to_goal_reached_row_by_row() -> None:
    env = ToyReach()
    s, _ = env.reset(seed=3)
    target = s.get_object_from_name("target")
    robot = s.get_object_from_name("robot")
    rows = []
    for offset in (0.05, 0.5, 0.0, 2.0):
        x = s.copy()
        x[robot][:2] = x[target][:2] + offset
        rows.append(x.data)
    verdicts = env.goals_reached(np.array(rows), s.layout)
    assert verdicts.dtype == np.bool_
    assert verdicts.tolist() == [True, False, True, False]


def test_actions_validated_and_clipped() -> None:
    env = ToyReach()
    s, _ = env.reset(seed=0)
    with pytest.raises(ValueError, match=r"ToyReach: action has shape \(3,\); expected shape"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step([np.nan, 0])
    with pytest.raises(ValueError, match="not numeric"):
        env.step(["a", "b"])
    assert env.transition(s, [5.0, -5.0])[0] == env.transition(s, [0.1, -0.1])[0]


def test_transition_does_not_disturb_live_episode() -> None:
    env = ToyReach()
    s, _ = env.reset(seed=0)
    env.transition(s, [0.1, 0.1])
    assert env.get_state() == s


def test_step_before_reset_is_a_clear_error() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        ToyReach().step(np.zeros(2))


def test_metadata_documents_the_env() -> None:
    env = ToyReach(num_pebbles=4)
    md = env.metadata
    assert md["description"].startswith("A toy env")
    assert md["variant"] == "ToyReach(num_pebbles=4)"
    assert "autoreset_mode" in md and md["render_fps"] == 20
    _ = env.box_space
    assert "| 0 | robot | robot | x |" in md["observation_table"]


def test_missing_doc_section_is_reported() -> None:
    class Undocumented(ToyReach):
        """No sections."""

    with pytest.raises(ValueError, match="lacks the section"):
        Undocumented()


def test_render_modes() -> None:
    env = ToyReach(render_mode=None)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    frame = ToyReach()
    frame.reset(seed=0)
    img = frame.render()
    assert img is not None and img.shape == (32, 32, 3)
    with pytest.raises(ValueError, match="render_mode"):
        ToyReach(render_mode="human")


def test_pickled_env_keeps_state_and_rng() -> None:
    env = ToyReach()
    env.reset(seed=5)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.get_state() == env.get_state()
    assert clone.reset()[0] == env.reset()[0]


def test_registered_env_is_box_view_with_object_centric_unwrapped(toy_id: str) -> None:
    env = kinder_core.make(toy_id)
    obs, _ = env.reset(seed=0)
    assert isinstance(env.observation_space, gymnasium.spaces.Box)
    assert obs.shape == (3 + 3 + 2 * 2,)
    assert isinstance(env.unwrapped, kinder_core.ObjectCentricEnv)
    assert isinstance(kinder_core.make_object_centric(toy_id), ToyReach)
    assert env.spec is not None and env.spec.max_episode_steps == 50
    get_state = env.get_wrapper_attr("get_state")
    np.testing.assert_array_equal(get_state(), obs)


def test_sync_and_async_vector_envs_agree(toy_id: str) -> None:
    from kinder_core.testing import check_vector_consistency

    check_vector_consistency(toy_id)


def test_checker_accepts_unbounded_box_features() -> None:
    import gymnasium

    from kinder_core.testing import check_gymnasium_checker

    env_id = "kinder/UnboundedToyReach-v0"
    if env_id not in gymnasium.registry:
        gymnasium.register(
            id=env_id,
            entry_point="kinder_core.registration:make_box_env",
            kwargs={"env_entry_point": "toy_env:UnboundedToyReach"},
            max_episode_steps=50,
        )
    check_gymnasium_checker(env_id)
