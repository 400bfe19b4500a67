"""The batched environments against the single ones: same episodes, step by step, bit for bit."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError


def make_vec(env_id, num_envs, **kwargs):
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def lockstep(venv, singles, steps, rng, same_reward, check_end):
    """Step the batch and the single envs with the same random actions (some clipped), the single envs
    resetting the step after an episode end as next-step autoreset does; observations, rewards (by
    ``same_reward``) and ends must agree at every step. ``check_end(i, info, single_info, ended)``
    compares the step's info of copy i. Returns the number of episode ends covered."""
    pending, ends = [False] * len(singles), 0
    for t in range(steps):
        actions = rng.uniform(-1.2, 1.2, venv.action_space.shape).astype(np.float32)  # some clipped
        obs, rewards, terminated, truncated, info = venv.step(actions)
        assert venv.observation_space.contains(obs)
        for i, env in enumerate(singles):
            if pending[i]:
                expected, reward, term, trunc = env.reset()[0], 0.0, False, False
                pending[i] = False
            else:
                expected, reward, term, trunc, single_info = env.step(actions[i])
                pending[i] = term or trunc
                ends += pending[i]
                check_end(i, info, single_info, pending[i])
            np.testing.assert_array_equal(obs[i], expected, err_msg=f"step {t}, copy {i}")
            assert same_reward(rewards[i], reward), (t, i, rewards[i], reward)
            assert (terminated[i], truncated[i]) == (term, trunc)
    return ends


def assert_batch_matches_singles(scenario, *, env_id="FFSR-Residual-v0", num_envs=2, seed=3, steps=30):
    """A batch of ``scenario`` reproduces single envs seeded seed, seed+1, ...: first observations bit for bit,
    then ``steps`` lockstep decisions (rewards to 1e-12)."""
    venv = make_vec(env_id, num_envs, scenario=scenario)
    singles = [gym.make(env_id, scenario=scenario) for _ in range(num_envs)]
    obs, _ = venv.reset(seed=seed)
    np.testing.assert_array_equal(obs, np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]))
    lockstep(venv, singles, steps, np.random.default_rng(1), lambda a, b: a == pytest.approx(b, rel=1e-12, abs=1e-15),
             lambda *args: None)


@pytest.mark.parametrize(("env_id", "scenario", "steps"), [("FFSR-Residual-v0", "random", 250), ("FFSR-v0", "paper", 120)])
def test_vector_env_equals_single_envs(env_id, scenario, steps):
    """N copies seeded s, s+1, ... reproduce N single envs, autoresets (next-step mode) included."""
    n = 3
    venv = make_vec(env_id, n, scenario=scenario)
    singles = [gym.make(env_id, scenario=scenario) for _ in range(n)]
    obs, _ = venv.reset(seed=7)
    np.testing.assert_array_equal(obs, np.stack([env.reset(seed=7 + i)[0] for i, env in enumerate(singles)]))

    def check_end(i, info, single_info, ended):
        if ended:
            assert info["_score"][i] and info["score"][i] == single_info["score"]
            assert info["feasible"][i] == single_info["feasible"]

    ends = lockstep(venv, singles, steps, np.random.default_rng(0),
                    lambda a, b: a == pytest.approx(b, rel=1e-12, abs=1e-15), check_end)
    assert ends >= 3  # the comparison covered episode ends and resets


def test_vector_env_bad_input_names_the_field():
    venv = make_vec("FFSR-Residual-v0", 2)
    with pytest.raises(InvalidInputError, match="reset"):
        venv.step(np.zeros((2, 12)))
    venv.reset(seed=0)
    actions = np.zeros((2, 12))
    actions[1, 3] = np.nan
    with pytest.raises(InvalidInputError, match=r"copies \[1\] are not finite.*\[-1, 1\]"):
        venv.step(actions)
    with pytest.raises(InvalidInputError, match="shape"):
        venv.step(np.zeros((3, 12)))
    with pytest.raises(InvalidInputError, match="num_envs"):
        make_vec("FFSR-Residual-v0", 0)
    with pytest.raises(InvalidInputError, match="threads"):
        make_vec("FFSR-Residual-v0", 2, threads=10_000)
    with pytest.raises(InvalidInputError, match="backend"):
        make_vec("FFSR-Residual-v0", 2, backend="pinocchio")
    with pytest.raises(TypeError, match="scenrio"):
        make_vec("FFSR-Residual-v0", 2, scenrio="paper")  # a typo is not silently ignored


def test_vector_env_episode_trajectory_scores_like_simulate():
    """A zero residual is the reference planner: the copy's trajectory equals ``simulate``'s."""
    venv = make_vec("FFSR-Residual-v0", 2, scenario="free_space")
    venv.reset(seed=0)
    for _ in range(5):
        venv.step(np.zeros((2, 12), dtype=np.float32))
    reference = ffsr_gym.simulate("free_space")
    trajectory = venv.unwrapped.trajectory(1) if hasattr(venv, "unwrapped") else venv.trajectory(1)
    np.testing.assert_allclose(trajectory.q, reference.q[:len(trajectory.t)], rtol=0, atol=1e-12)


@pytest.mark.parametrize(("env_id", "task", "steps"), [("FFSR-Residual-v2", "easy", 230), ("FFSR-v2", "medium", 230),
                                                       ("FFSR-Residual-v2", "hard", 230)])
def test_v2_vector_env_equals_single_envs(env_id, task, steps):
    """Batched v2: same observations, rewards, ends, scores and task draws as single envs seeded s, s+1, ..."""
    n = 3
    venv = make_vec(env_id, n, task=task, dense_shaping=True)
    singles = [gym.make(env_id, task=task, dense_shaping=True) for _ in range(n)]
    obs, info = venv.reset(seed=11)
    resets = [env.reset(seed=11 + i) for i, env in enumerate(singles)]
    np.testing.assert_array_equal(obs, np.stack([r[0] for r in resets]))
    assert list(info["task_seed"]) == [r[1].get("task_seed", -1) for r in resets]

    def check_end(i, info, single_info, ended):
        assert info["cost"][i] == single_info["cost"]
        if ended:
            assert info["_score"][i]
            for key in ("score", "success", "failure", "smoothness_cost", "paper_B"):
                assert info[key][i] == single_info[key], key

    ends = lockstep(venv, singles, steps, np.random.default_rng(1), lambda a, b: a == b, check_end)
    assert ends >= 3


def test_v2_vector_env_pickles_mid_episode():
    venv = make_vec("FFSR-Residual-v2", 3, task="easy")
    venv.reset(seed=5)
    rng = np.random.default_rng(0)
    venv.step(rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32))
    clone = pickle.loads(pickle.dumps(venv))
    for _ in range(4):  # the copies' kept plans against the clone's fresh ones: same numbers
        actions = rng.uniform(-1, 1, venv.action_space.shape).astype(np.float32)
        a, b = venv.step(actions), clone.step(actions)
        for x, y in zip(a[:4], b[:4]):
            np.testing.assert_array_equal(x, y)


def test_v2_vector_env_refuses_what_it_cannot_batch():
    with pytest.raises(InvalidInputError, match="terminate_on_violation"):
        make_vec("FFSR-v2", 2, terminate_on_violation=False)
    with pytest.raises(InvalidInputError, match="split"):
        make_vec("FFSR-v2", 2, task="easy", split="dev")


def test_vector_env_renders_copy_0_as_the_single_env_draws_it():
    """``render_mode="rgb_array"``: one frame, copy 0's, pixel for pixel the single env's frame after the same steps."""
    venv = gym.make_vec("FFSR-v2", num_envs=2, task="easy", vectorization_mode="vector_entry_point",
                        render_mode="rgb_array")
    single = gym.make("FFSR-v2", task="easy", backend="kernel", render_mode="rgb_array")
    venv.reset(seed=3)
    single.reset(seed=3)
    actions = np.array([[0.1, -0.2], [0.5, 0.5]], dtype=np.float32)
    for _ in range(12):
        venv.step(actions)
        single.step(actions[0])
    frames = venv.render()
    assert isinstance(frames, tuple) and len(frames) == 1 and frames[0].shape[2] == 3
    assert np.array_equal(frames[0], single.render())
    venv.close()
    with pytest.raises(InvalidInputError, match="rgb_array"):
        make_vec("FFSR-v2", 2, render_mode="human")


def test_v2_vector_env_without_autoreset_holds_ended_copies():
    """``autoreset_mode="Disabled"``: an ended copy is not stepped again (same state, observation, no reward)
    while the others go on; its episode is the single env's."""
    from ffsr_gym.environments.vector_env import FFSRVectorEnv

    venv = FFSRVectorEnv(2, "v2", task="hard", split="test", autoreset_mode="Disabled")
    venv.reset(seed=[0, 1], options={"task_index": [0, 5]})
    ended_at, held = {}, {}
    for step in range(200):
        obs, rewards, terminated, truncated, info = venv.step_with_parameters(0.1, 1.5)  # breaks the rate limit early
        for i in np.flatnonzero(terminated | truncated):
            assert i not in ended_at
            ended_at[i], held[i] = step, (obs[i].copy(), int(venv.engine.K[i]), info["score"][i])
        for i, (obs_i, k_i, _) in held.items():
            if ended_at[i] < step:
                np.testing.assert_array_equal(obs[i], obs_i)
                assert venv.engine.K[i] == k_i and rewards[i] == 0.0 and not terminated[i] and not truncated[i]
        if len(ended_at) == 2:
            break
    assert len(ended_at) == 2 and ended_at[0] != ended_at[1]
    for i, index in enumerate((0, 5)):
        single = gym.make("FFSR-v2", task="hard", split="test")
        single.reset(seed=i, options={"task_index": index})
        while not any((step := single.unwrapped.step_with_parameters(0.1, 1.5))[2:4]):
            pass
        assert step[4]["score"] == held[i][2] and single.unwrapped.rollout.k == held[i][1]
    with pytest.raises(InvalidInputError, match="autoreset_mode"):
        FFSRVectorEnv(2, "v2", task="hard", autoreset_mode="EveryStep")
    for mask in ([True, False], np.array([False, False]), np.array([1, 0])):
        with pytest.raises(InvalidInputError, match="reset_mask"):
            venv.reset(options={"reset_mask": mask})


def test_v2_play_out_gives_the_trajectories_of_decision_after_decision():
    """``play_out_with_parameters``: whole episodes in one kernel call end where, and as, decision after decision
    of ``step_with_parameters`` does (trajectory arrays and episode scores bit for bit), for two copies that end at
    different decisions."""
    from ffsr_gym.environments.vector_env import FFSRVectorEnv

    def played(whole):
        venv = FFSRVectorEnv(2, "v2", task="hard", split="test", autoreset_mode="Disabled", record_trajectories=True)
        venv.reset(seed=[0, 1], options={"task_index": [0, 5]})
        if whole:
            terminated, truncated, _ = venv.play_out_with_parameters(0.1, 1.5)
            assert (terminated | truncated).all()
        else:
            ended = np.zeros(2, dtype=bool)
            while not ended.all():
                _, _, term, trunc, _ = venv.step_with_parameters(0.1, 1.5)
                ended |= term | trunc
        return venv, [venv.trajectory(i) for i in range(2)], [venv.engine.results[i] for i in range(2)]

    _, whole, scores = played(True)
    _, stepped, stepped_scores = played(False)
    assert scores == stepped_scores and scores[0].failure == "rate_limit"
    assert len(whole[0].t) != len(whole[1].t)
    for a, b in zip(whole, stepped):
        assert len(a.t) == len(b.t)
        for name in ("q", "v", "dq_joints", "ee_position_error_m", "clearance_m", "self_clearance_m", "mu", "sigma_min"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    with pytest.raises(InvalidInputError, match="not a residual env"):
        FFSRVectorEnv(2, "v2", residual=True, task="hard").play_out_with_parameters(0.3, 4.0)
    with pytest.raises(InvalidInputError, match="reset"):
        FFSRVectorEnv(2, "v2", task="hard").play_out_with_parameters(0.3, 4.0)


def test_the_default_thread_count_reads_ffsr_gym_threads(monkeypatch):
    """``FFSR_GYM_THREADS`` sets the batched envs' default threads (bounded by the cores); a malformed value is
    refused by name; ``threads=`` outside 1..cores is refused with the allowed range."""
    from ffsr_gym.environments.vector_env import THREADS_VARIABLE, available_cores, default_threads

    cores = available_cores()
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    assert default_threads(cores) == cores
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    venv = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point")
    assert venv.unwrapped.engine.threads == 1
    monkeypatch.setenv(THREADS_VARIABLE, str(cores + 7))
    assert default_threads(cores) == cores
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv(THREADS_VARIABLE, bad)
        with pytest.raises(InvalidInputError, match="FFSR_GYM_THREADS"):
            default_threads(cores)
    monkeypatch.delenv(THREADS_VARIABLE)
    with pytest.raises(InvalidInputError, match=f"allowed: an integer from 1 to {cores}"):
        gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point", threads=cores + 1)
