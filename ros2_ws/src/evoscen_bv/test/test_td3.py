"""TD3: the target computation on a hand-computed batch, numpy inference, learning a toy task."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from evoscen_bv.td3 import TD3, NumpyActor, ReplayBuffer, TD3Params, export_actor, td3_target  # noqa: E402


def test_clipped_double_q_target_by_hand():
    reward = torch.tensor([[1.0], [2.0], [-1.0]])
    not_done = torch.tensor([[1.0], [0.0], [1.0]])
    q1 = torch.tensor([[3.0], [5.0], [-2.0]])
    q2 = torch.tensor([[4.0], [1.0], [-3.0]])
    y = td3_target(reward, not_done, 0.9, q1, q2)
    # y = r + γ (1 - done) min(Q1', Q2'): 1 + 0.9·3, 2 (terminal), -1 + 0.9·(-3)
    assert y.numpy().ravel() == pytest.approx([3.7, 2.0, -3.7])


def _constant_nets(agent: TD3, actor_out: float, w1: float, c1: float, w2: float, c2: float) -> None:
    """Target actor outputs tanh⁻¹-free constant ``actor_out``; target critics Q_k = w_k·a + c_k."""
    with torch.no_grad():
        a = agent.actor_target
        for layer in (a.l1, a.l2, a.l3):
            layer.weight.zero_()
            layer.bias.zero_()
        a.l3.bias.fill_(float(np.arctanh(actor_out)))
        c = agent.critic_target
        for layer in (c.l1, c.l2, c.l3, c.l4, c.l5, c.l6):
            layer.weight.zero_()
            layer.bias.zero_()
        # hidden unit 0 of each critic passes the action (last input) through the ReLUs: a + 1 > 0
        for first, second, last, w, b in ((c.l1, c.l2, c.l3, w1, c1), (c.l4, c.l5, c.l6, w2, c2)):
            first.weight[0, -1] = 1.0
            first.bias[0] = 1.0
            second.weight[0, 0] = 1.0
            last.weight[0, 0] = w
            last.bias[0] = b - w  # Q = w (a + 1) + b - w = w a + b


def test_target_uses_smoothed_clipped_action_and_the_smaller_critic():
    agent = TD3(state_dim=2, action_dim=1, max_action=1.0, params=TD3Params(discount=0.5), seed=0)
    _constant_nets(agent, actor_out=0.6, w1=2.0, c1=1.0, w2=-1.0, c2=3.0)
    next_state = torch.zeros((3, 2))
    reward = torch.tensor([[0.0], [1.0], [1.0]])
    not_done = torch.tensor([[1.0], [1.0], [0.0]])
    # standard normal draws ×0.2 = noise 0.2, 10 → clipped 0.5, and -1 → -0.2
    smoothing = torch.tensor([[1.0], [50.0], [-1.0]])
    y = agent.target_q(next_state, reward, not_done, smoothing).numpy().ravel()
    # row 0: a' = 0.6 + 0.2 = 0.8;  Q1 = 2·0.8 + 1 = 2.6, Q2 = -0.8 + 3 = 2.2 → y = 0 + 0.5·2.2 = 1.1
    # row 1: a' = min(0.6 + 0.5, 1) = 1.0; Q1 = 3, Q2 = 2 → y = 1 + 0.5·2 = 2.0
    # row 2: terminal → y = r = 1
    assert y == pytest.approx([1.1, 2.0, 1.0], abs=1e-6)


def test_numpy_forward_equals_torch(tmp_path):
    agent = TD3(state_dim=7, action_dim=1, max_action=1.0, params=TD3Params(hidden=16), seed=3)
    export_actor(agent.actor, tmp_path / "a.npz")
    actor = NumpyActor.load(tmp_path / "a.npz")
    x = np.random.default_rng(0).normal(size=(50, 7))
    with torch.no_grad():
        ref = agent.actor(torch.as_tensor(x, dtype=torch.float32)).numpy()
    assert actor.forward(x) == pytest.approx(ref, abs=1e-5)


def test_bad_policy_files_name_the_file(tmp_path):
    with pytest.raises(ValueError, match="policy file not found"):
        NumpyActor.load(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(ValueError, match=r"junk\.npz: not a readable \.npz"):
        NumpyActor.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "partial.npz", W1=np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"partial\.npz: not an actor weight file"):
        NumpyActor.load(tmp_path / "partial.npz")


def test_replay_buffer_ring_and_seeded_sampling():
    rb = ReplayBuffer(1, 1, max_size=3)
    for k in range(5):
        rb.add([k], [0.0], [k + 1], float(k), k == 4)
    assert rb.size == 3
    assert sorted(rb.state[:, 0]) == [2.0, 3.0, 4.0]
    a = rb.sample(8, np.random.default_rng(1))[0]
    b = rb.sample(8, np.random.default_rng(1))[0]
    assert np.array_equal(a, b)


def _toy_episode(policy, x0: float, steps: int = 20) -> float:
    """1-D regulation: x' = clip(x + 0.5 a, -2, 2), reward -x'²; the optimum drives x to 0."""
    x, ret = x0, 0.0
    for _ in range(steps):
        a = float(policy(np.array([x]))[0])
        x = float(np.clip(x + 0.5 * a, -2.0, 2.0))
        ret += -x * x
    return ret


def test_seeded_td3_learns_a_toy_control_task():
    torch.set_num_threads(1)
    params = TD3Params(hidden=32, batch_size=64, start_steps=300, discount=0.9)
    agent = TD3(1, 1, 1.0, params, seed=0)
    rng = np.random.default_rng(0)
    rb = ReplayBuffer(1, 1, 5000)
    t = 0
    while t < 2500:
        x = float(rng.uniform(-2, 2))
        for _ in range(20):
            s = np.array([x])
            a = rng.uniform(-1, 1, 1) if t < params.start_steps else agent.explore(s, rng)
            x = float(np.clip(x + 0.5 * a[0], -2.0, 2.0))
            rb.add(s, a, np.array([x]), -x * x, False)
            t += 1
            if t >= params.start_steps:
                agent.train(rb, rng)
    starts = np.linspace(-2, 2, 9)
    learned = np.mean([_toy_episode(agent.select_action, x0) for x0 in starts])
    idle = np.mean([_toy_episode(lambda s: np.zeros(1), x0) for x0 in starts])
    best = np.mean([_toy_episode(lambda s: np.clip(-2.0 * s, -1, 1), x0) for x0 in starts])
    # doing nothing costs ~26.7 per episode; the optimal bang-bang policy ~1.1
    assert idle < -25.0
    assert learned > best - 1.0


def test_policy_bank_routes_each_row_through_its_own_actor(tmp_path):
    from evoscen_bv.learned import PolicyBank

    actors = []
    for seed in (1, 2, 3):
        agent = TD3(state_dim=30, action_dim=1, max_action=1.0, params=TD3Params(hidden=8), seed=seed)
        export_actor(agent.actor, tmp_path / f"{seed}.npz")
        actors.append(NumpyActor.load(tmp_path / f"{seed}.npz"))
    x = np.random.default_rng(0).normal(size=(9, 30))
    x[x < 0.5] = 0.0  # sparse, like the decision grid
    col = np.array([0, 1, 2, 2, 1, 0, 0, 2, 1])
    expected = np.array([actors[c].forward(x[r:r + 1])[0, 0] for r, c in enumerate(col)])
    assert PolicyBank(actors).forward(x, col) == pytest.approx(expected, abs=1e-12)
