"""Twin Delayed DDPG (TD3, Fujimoto, van Hoof, Meger 2018; docs/method.md §3.4), after the authors' reference.

The learner reads like the algorithm (:meth:`TD3.train`): sample a batch, smooth the target
policy with clipped noise, take the minimum of the twin target critics (clipped double-Q),
regress both critics on it, and every ``policy_freq`` updates improve the actor on Q1 and
move the targets by Polyak averaging. Hyper-parameters are :class:`TD3Params` (the
reference's defaults unless noted).

Training runs in PyTorch (CPU). Inference does not: :func:`export_actor` writes the actor's
weights to a small ``.npz`` and :class:`NumpyActor` evaluates them with plain numpy — the
BV node then needs no torch (importing torch costs seconds) and the in-process runner and
the node compute the same floats with the same code.

Seeding: the networks are initialised under ``torch.manual_seed(seed)``; every numpy draw
(replay sampling, exploration noise) comes from a :class:`numpy.random.Generator` passed in,
and the target-policy noise is drawn from that generator too, so one seed fixes a run
(with ``torch.set_num_threads(1)``, which the training script sets).
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ACTIVATIONS = ("relu", "relu", "tanh")
"""Actor layers: two hidden ReLU layers and a tanh output scaled by ``max_action``."""


@dataclass(frozen=True)
class TD3Params:
    """TD3 hyper-parameters (defaults: the reference implementation, except where noted)."""

    discount: float = 0.99
    """γ of the target ``y = r + γ (1 - done) min(Q1', Q2')``."""
    tau: float = 0.005
    """Polyak factor of the target networks: θ' ← τ θ + (1 - τ) θ'."""
    policy_noise: float = 0.2
    """Std of the target-policy smoothing noise (in units of ``max_action``)."""
    noise_clip: float = 0.5
    """The smoothing noise is clipped to ±``noise_clip`` (units of ``max_action``)."""
    policy_freq: int = 2
    """Actor and target updates every ``policy_freq`` critic updates (delayed updates)."""
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    hidden: int = 64
    """Units of each hidden layer [choice: 64, not the reference's 256 — the policies are
    small problems, the machine has 2 cores, and inference runs for every BV every step]."""
    batch_size: int = 128
    """Mini-batch size [choice: 128 instead of 256, for speed on CPU]."""
    expl_noise: float = 0.1
    """Std of the Gaussian exploration noise added to the actor's action (units of ``max_action``)."""
    start_steps: int = 1000
    """Uniformly random actions for the first steps, before learning starts."""


def _torch():
    import torch  # imported lazily: inference (NumpyActor) must not need torch

    return torch


def build_actor(state_dim: int, action_dim: int, max_action: float, hidden: int):
    """The actor network π(s) = max_action · tanh(W3 relu(W2 relu(W1 s)))."""
    torch = _torch()
    nn = torch.nn

    class Actor(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.l1 = nn.Linear(state_dim, hidden)
            self.l2 = nn.Linear(hidden, hidden)
            self.l3 = nn.Linear(hidden, action_dim)
            self.max_action = max_action

        def forward(self, state):
            a = torch.relu(self.l1(state))
            a = torch.relu(self.l2(a))
            return self.max_action * torch.tanh(self.l3(a))

    return Actor()


def build_critic(state_dim: int, action_dim: int, hidden: int):
    """Twin critics Q1, Q2 over the concatenated (state, action)."""
    torch = _torch()
    nn = torch.nn

    class Critic(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.l1 = nn.Linear(state_dim + action_dim, hidden)  # Q1
            self.l2 = nn.Linear(hidden, hidden)
            self.l3 = nn.Linear(hidden, 1)
            self.l4 = nn.Linear(state_dim + action_dim, hidden)  # Q2
            self.l5 = nn.Linear(hidden, hidden)
            self.l6 = nn.Linear(hidden, 1)

        def forward(self, state, action):
            sa = torch.cat([state, action], 1)
            q1 = self.l3(torch.relu(self.l2(torch.relu(self.l1(sa)))))
            q2 = self.l6(torch.relu(self.l5(torch.relu(self.l4(sa)))))
            return q1, q2

        def Q1(self, state, action):  # the reference's name
            sa = torch.cat([state, action], 1)
            return self.l3(torch.relu(self.l2(torch.relu(self.l1(sa)))))

    return Critic()


class ReplayBuffer:
    """A ring buffer of transitions (s, a, s', r, not_done) in float32 numpy arrays."""

    def __init__(self, state_dim: int, action_dim: int, max_size: int) -> None:
        self.max_size = int(max_size)
        self.ptr = 0
        self.size = 0
        self.state = np.zeros((self.max_size, state_dim), dtype=np.float32)
        self.action = np.zeros((self.max_size, action_dim), dtype=np.float32)
        self.next_state = np.zeros((self.max_size, state_dim), dtype=np.float32)
        self.reward = np.zeros((self.max_size, 1), dtype=np.float32)
        self.not_done = np.zeros((self.max_size, 1), dtype=np.float32)

    def add(self, state, action, next_state, reward: float, done: bool) -> None:
        self.state[self.ptr] = state
        self.action[self.ptr] = action
        self.next_state[self.ptr] = next_state
        self.reward[self.ptr] = reward
        self.not_done[self.ptr] = 1.0 - float(done)
        self.ptr = (self.ptr + 1) % self.max_size
        self.size = min(self.size + 1, self.max_size)

    def sample(self, batch_size: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        ind = rng.integers(0, self.size, size=batch_size)
        return self.state[ind], self.action[ind], self.next_state[ind], self.reward[ind], self.not_done[ind]

    def save(self, path: Path) -> None:
        n = self.size
        np.savez(path, state=self.state[:n], action=self.action[:n], next_state=self.next_state[:n],
                 reward=self.reward[:n], not_done=self.not_done[:n], ptr=self.ptr)

    def load(self, path: Path) -> None:
        with np.load(path) as z:
            n = z["state"].shape[0]
            self.state[:n] = z["state"]
            self.action[:n] = z["action"]
            self.next_state[:n] = z["next_state"]
            self.reward[:n] = z["reward"]
            self.not_done[:n] = z["not_done"]
            self.size = n
            self.ptr = int(z["ptr"])


def td3_target(reward, not_done, discount: float, target_q1, target_q2):
    """Clipped double-Q target y = r + γ·(1 - done)·min(Q1', Q2') (docs/method.md §3.4)."""
    torch = _torch()
    return reward + not_done * discount * torch.min(target_q1, target_q2)


class TD3:
    """The TD3 learner (actor, twin critics, their targets and optimisers)."""

    def __init__(self, state_dim: int, action_dim: int, max_action: float, params: TD3Params, seed: int) -> None:
        torch = _torch()
        torch.manual_seed(seed)
        self.params = params
        self.state_dim = state_dim
        self.action_dim = action_dim
        self.max_action = float(max_action)
        self.actor = build_actor(state_dim, action_dim, max_action, params.hidden)
        self.actor_target = copy.deepcopy(self.actor)
        self.actor_optimizer = torch.optim.Adam(self.actor.parameters(), lr=params.actor_lr)
        self.critic = build_critic(state_dim, action_dim, params.hidden)
        self.critic_target = copy.deepcopy(self.critic)
        self.critic_optimizer = torch.optim.Adam(self.critic.parameters(), lr=params.critic_lr)
        self.total_it = 0

    def select_action(self, state: np.ndarray) -> np.ndarray:
        """The deterministic policy action for one state (torch; training only)."""
        torch = _torch()
        with torch.no_grad():
            s = torch.as_tensor(np.asarray(state, dtype=np.float32).reshape(1, -1))
            return self.actor(s).numpy().reshape(-1).astype(float)

    def explore(self, state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Policy action plus Gaussian exploration noise, clipped to ±max_action."""
        noise = rng.normal(0.0, self.max_action * self.params.expl_noise, size=self.action_dim)
        return np.clip(self.select_action(state) + noise, -self.max_action, self.max_action)

    def target_q(self, next_state, reward, not_done, smoothing):
        """The critics' regression target for a batch; ``smoothing`` is standard normal noise."""
        torch = _torch()
        p = self.params
        with torch.no_grad():
            # target policy smoothing: clipped noise on the target actor's action
            noise = (smoothing * p.policy_noise * self.max_action).clamp(-p.noise_clip * self.max_action,
                                                                         p.noise_clip * self.max_action)
            next_action = (self.actor_target(next_state) + noise).clamp(-self.max_action, self.max_action)
            # clipped double-Q: the smaller of the two target critics
            target_q1, target_q2 = self.critic_target(next_state, next_action)
            return td3_target(reward, not_done, p.discount, target_q1, target_q2)

    def train(self, replay: ReplayBuffer, rng: np.random.Generator) -> dict[str, float]:
        """One TD3 update from a mini-batch of ``replay``; returns the losses."""
        torch = _torch()
        F = torch.nn.functional
        p = self.params
        self.total_it += 1
        state, action, next_state, reward, not_done = (torch.as_tensor(x) for x in replay.sample(p.batch_size, rng))
        smoothing = rng.standard_normal(size=tuple(action.shape)).astype(np.float32)

        target_q = self.target_q(next_state, reward, not_done, torch.as_tensor(smoothing))
        current_q1, current_q2 = self.critic(state, action)
        critic_loss = F.mse_loss(current_q1, target_q) + F.mse_loss(current_q2, target_q)
        self.critic_optimizer.zero_grad()
        critic_loss.backward()
        self.critic_optimizer.step()
        losses = {"critic_loss": critic_loss.item()}

        # delayed policy updates
        if self.total_it % p.policy_freq == 0:
            actor_loss = -self.critic.Q1(state, self.actor(state)).mean()
            self.actor_optimizer.zero_grad()
            actor_loss.backward()
            self.actor_optimizer.step()
            losses["actor_loss"] = actor_loss.item()
            # Polyak averaging of the targets
            with torch.no_grad():
                for net, target in ((self.critic, self.critic_target), (self.actor, self.actor_target)):
                    for param, target_param in zip(net.parameters(), target.parameters()):
                        target_param.mul_(1.0 - p.tau).add_(p.tau * param)
        return losses

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict:
        return {
            "actor": self.actor.state_dict(), "actor_target": self.actor_target.state_dict(),
            "critic": self.critic.state_dict(), "critic_target": self.critic_target.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "total_it": self.total_it, "params": asdict(self.params),
        }

    def load_state_dict(self, sd: dict) -> None:
        self.actor.load_state_dict(sd["actor"])
        self.actor_target.load_state_dict(sd["actor_target"])
        self.critic.load_state_dict(sd["critic"])
        self.critic_target.load_state_dict(sd["critic_target"])
        self.actor_optimizer.load_state_dict(sd["actor_optimizer"])
        self.critic_optimizer.load_state_dict(sd["critic_optimizer"])
        self.total_it = int(sd["total_it"])


# ---------------------------------------------------------------------- numpy inference
def export_actor(actor, path: Path) -> None:
    """Write a torch actor's weights to ``path`` (.npz): W1, b1, W2, b2, W3, b3, max_action."""
    sd = {k: v.detach().cpu().numpy() for k, v in actor.state_dict().items()}
    np.savez(path, W1=sd["l1.weight"].T, b1=sd["l1.bias"], W2=sd["l2.weight"].T, b2=sd["l2.bias"],
             W3=sd["l3.weight"].T, b3=sd["l3.bias"], max_action=np.float64(actor.max_action))


class NumpyActor:
    """The actor's forward pass in numpy (float64), from an ``.npz`` written by :func:`export_actor`.

    ``forward(states)`` takes a batch ``(m, state_dim)`` and returns ``(m, action_dim)``.
    Invalid files raise ``ValueError`` with one line naming the file and what is wrong.
    """

    KEYS = ("W1", "b1", "W2", "b2", "W3", "b3", "max_action")

    def __init__(self, weights: dict[str, np.ndarray], source: str = "<memory>") -> None:
        missing = [k for k in self.KEYS if k not in weights]
        if missing:
            raise ValueError(f"{source}: not an actor weight file (missing arrays {missing}; expected {list(self.KEYS)})")
        w = {k: np.asarray(weights[k], dtype=np.float64) for k in self.KEYS}
        shapes_ok = (w["W1"].ndim == 2 and w["W2"].shape == (w["W1"].shape[1], w["W1"].shape[1])
                     and w["W3"].ndim == 2 and w["W3"].shape[0] == w["W1"].shape[1]
                     and w["b1"].shape == (w["W1"].shape[1],) and w["b2"].shape == (w["W2"].shape[1],)
                     and w["b3"].shape == (w["W3"].shape[1],))
        if not shapes_ok:
            raise ValueError(f"{source}: actor weight shapes are inconsistent "
                             f"(W1 {w['W1'].shape}, W2 {w['W2'].shape}, W3 {w['W3'].shape})")
        if not all(np.all(np.isfinite(v)) for v in w.values()):
            raise ValueError(f"{source}: actor weights contain NaN or infinite values")
        self.W1, self.b1, self.W2, self.b2, self.W3, self.b3 = (w[k] for k in self.KEYS[:6])
        self.max_action = float(w["max_action"])
        self.state_dim = self.W1.shape[0]
        self.action_dim = self.W3.shape[1]

    def __deepcopy__(self, memo: dict) -> NumpyActor:
        """Itself while its weights are read-only (those :func:`evoscen_bv.learned.load_policies` hands out,
        shared by every driver of the process); else a copy of its own."""
        if not any(w.flags.writeable for w in (self.W1, self.b1, self.W2, self.b2, self.W3, self.b3)):
            return self
        out = NumpyActor.__new__(NumpyActor)
        memo[id(self)] = out
        out.__dict__.update(copy.deepcopy(self.__dict__, memo))
        return out

    @classmethod
    def load(cls, path: Path) -> NumpyActor:
        path = Path(path)
        try:
            with np.load(path) as z:
                weights = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise ValueError(f"{path}: policy file not found") from None
        except Exception as exc:  # noqa: BLE001 - a corrupt file is named, not a traceback
            raise ValueError(f"{path}: not a readable .npz file ({type(exc).__name__})") from None
        return cls(weights, str(path))

    def forward(self, states: np.ndarray) -> np.ndarray:
        """π(s) for a batch of states."""
        h = np.maximum(states @ self.W1 + self.b1, 0.0)
        h = np.maximum(h @ self.W2 + self.b2, 0.0)
        return self.max_action * np.tanh(h @ self.W3 + self.b3)
