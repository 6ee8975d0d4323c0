"""The level-k training pipeline (docs/method.md §3.3): five stages, resumable, with curves and model cards.

Stages, in order, and what each writes into the output directory ``OUT``:

=============  ================================================  =====================
stage          learns                                            policy file
=============  ================================================  =====================
control        car-following controller (:class:`CarFollowingEnv`)  ``controller.npz``
level1         mutual decisions among level-0 traffic            ``level1_mutual.npz``
level2         mutual decisions among level-1 mutual traffic     ``mutual.npz``
competitive    competitive decisions among level-2 mutual        ``competitive.npz``
cooperative    cooperative decisions among level-2 mutual        ``cooperative.npz``
=============  ================================================  =====================

Per stage ``OUT/<stage>/`` holds ``curve.csv`` and ``curve.png`` (episode returns),
``eval.csv`` (periodic evaluations), the checkpoint while it runs, and ``done.json`` when
finished; ``OUT/<policy>.md`` is the model
card (stage, steps, seed, coefficients, final metrics, steps to convergence, wall time, the
command and git commit that reproduce it). The control stage also writes
``OUT/control/gap_kde.png``, the distribution of the gap held in evaluation.

Policy selection [choice]: every ``env.eval_every_steps`` training steps and at the end,
the deterministic actor is evaluated on fixed evaluation seeds (disjoint from training's);
the stage's policy is the best of these evaluations (its step is ``selected_step`` in the
model card). TD3 is not monotone: a controller trained 40k steps, exported at the end,
held a 35.7 m mean gap where the same run at 30k steps held 23 m.

[choice] Settling. The evaluation return is nearly blind to two defects of a controller:
a period-2 limit cycle (±2.5 m/s² alternating every step moves the gap by ~1 cm, so the
reward hardly changes) and the gap it settles at (10 m off the target costs 0.01 per step).
Trained with V at the view's edge, 27 of 35 periodic evaluations of two training seeds
chattered so, and the settled gaps of one run's checkpoints ranged from 9 to 45 m. With
``env.control_settling_check`` (default) every controller evaluation also runs
:func:`settling_check` — four learned followers behind a leader at constant speed — and
the stage's policy is the best return among the evaluations that pass (no collision, mean
gap after the approach within g ± 5 m, at most 1 % acceleration flips); when none passes,
the best return overall, and the model card says so. False: the return alone, as before.
The check's platoon differs from the one ``test_shipped_policies`` runs (other speeds and
starting gaps), so that test stays an independent check of the shipped controller.

Seeding: stage ``k`` of seed ``S`` uses ``SeedSequence([S, k])`` for the torch seed, the
learner's numpy generator (exploration noise, replay sampling) and the episode seeds.
Resuming: a finished stage (``done.json``) is skipped; an unfinished one restarts from its
last checkpoint (taken at episode ends, every ``checkpoint_every`` steps: the learner,
optimisers, replay buffer, generator state and curve) and continues exactly as an
uninterrupted run would.
"""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from evoscen_sim.errors import InputError

from .training_config import STAGES, TrainingConfig, load_training_config

POLICY_OF_STAGE = {"control": "controller", "level1": "level1_mutual", "level2": "mutual",
                   "competitive": "competitive", "cooperative": "cooperative"}
NEEDS = {"control": (), "level1": ("controller",), "level2": ("controller", "level1_mutual"),
         "competitive": ("controller", "mutual"), "cooperative": ("controller", "mutual")}
KIND_OF_STAGE = {"level1": "mutual", "level2": "mutual", "competitive": "competitive", "cooperative": "cooperative"}
FROZEN_OF_STAGE = {"level1": None, "level2": "level1_mutual", "competitive": "mutual", "cooperative": "mutual"}
EVAL_EPISODES = {"control": 6, "decision": 4}
"""Evaluation episodes (deterministic policy, seeds disjoint from training) after each stage."""


SETTLING_STEPS = 700
"""Steps of the settling check (70 s); the gaps of the last 400 count (after the approach)."""
SETTLING_FLIP_SHARE = 0.01
"""At most this share of consecutive follower accelerations flip sign with |a| > 1 m/s² [choice:
the shipped controller 0.000, the chattering ones 0.1-1.0]."""
SETTLING_BAND_M = 5.0
"""The mean settled gap must lie within g ± this (m) [choice: the band test_shipped_policies holds]."""


def settling_check(controller, config: TrainingConfig, road) -> dict:
    """Four learned followers (``controller``, the config's run-time profile) behind a leader at
    a constant 22 m/s in lane 3, starting 55, 10, 40 and 25 m apart at 26, 20, 25 and 23 m/s;
    700 steps. Returns the mean gap (m) and the share of acceleration flips over the last 400
    steps, the collisions, and ``settled`` (see the module docstring)."""
    from evoscen_sim.loop.hand_built import hand_built_world

    from .learned import LearnedDriver

    s = [300.0, 240.0, 225.0, 180.0, 150.0]  # bumper gaps = Δs - 5 m: 55, 10, 40, 25
    w = hand_built_world(road, s=s, lane=[3] * 5, speed=[22.0, 26.0, 20.0, 25.0, 23.0])
    followers = LearnedDriver(np.arange(1, 5), controller, {}, config, np.random.default_rng(0), w.vehicle)
    gaps, accels, collisions = [], [], 0
    for k in range(SETTLING_STEPS):
        throttle = np.zeros(5)
        throttle[1:] = followers.throttle(w)
        collisions += len(w.step(throttle, np.zeros(5, dtype=np.int64)).collisions)
        if k >= SETTLING_STEPS - 400:
            gaps.append(w.neighborhood().gap_front_m[1:, 2].copy())
            accels.append(w.accel[1:].copy())
    return settling_figures(np.array(gaps), np.array(accels), collisions, config.car_following.target_gap_m)


def settling_figures(gaps: np.ndarray, accels: np.ndarray, collisions: int, target_gap_m: float) -> dict:
    """The settling check's figures from the followers' gaps and accelerations (steps x followers)."""
    a0, a1 = accels[:-1], accels[1:]
    flips = (np.abs(a0) > 1.0) & (np.abs(a1) > 1.0) & (np.sign(a0) != np.sign(a1))
    mean_gap = float(gaps.mean())
    flip_share = float(flips.mean())
    settled = collisions == 0 and abs(mean_gap - target_gap_m) <= SETTLING_BAND_M and flip_share <= SETTLING_FLIP_SHARE
    return {"settled_gap_m": round(mean_gap, 2), "flip_share": round(flip_share, 4), "settling_collisions": collisions,
            "settled": bool(settled)}


def selection_key(e: dict) -> tuple:
    """Rank of a periodic evaluation: settled first (evaluations without the check count as
    settled), then the return, then the later step."""
    return (e.get("settled", True), e["eval_mean_return"], e["step"])


@dataclass
class StageResult:
    stage: str
    policy: str
    steps: int
    wall_s: float
    steps_to_convergence: int
    metrics: dict


def stage_seeds(seed: int, stage: str) -> tuple[int, np.random.Generator, int]:
    """(torch seed, learner generator, episode-seed base) of ``stage``."""
    ss = np.random.SeedSequence([int(seed), STAGES.index(stage)])
    torch_ss, learner_ss, episode_ss = ss.spawn(3)
    return (int(torch_ss.generate_state(1)[0]), np.random.default_rng(learner_ss),
            int(episode_ss.generate_state(1)[0]))


def episode_seed(base: int, episode: int, evaluation: bool = False) -> int:
    return int(np.random.SeedSequence([base, int(episode), int(evaluation)]).generate_state(1)[0])


def git_commit() -> str:
    """HEAD of the repository this package lives in (``+dirty`` with uncommitted changes), or ``unknown``."""
    here = Path(__file__).resolve()
    for cwd in (Path.cwd(), here.parent):
        try:
            head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
            if head.returncode != 0:
                continue
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                                   capture_output=True, text=True, timeout=10)
            return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
        except (OSError, subprocess.SubprocessError):
            continue
    return "unknown"


def steps_to_convergence(steps: np.ndarray, returns: np.ndarray, window: int = 10) -> int:
    """First step after which the moving average of episode returns (``window`` episodes)
    reaches 90 % of its rise from its first to its final value [choice]; 0 if it never rose."""
    if len(returns) < window + 1:
        return int(steps[-1]) if len(steps) else 0
    ma = np.convolve(returns, np.ones(window) / window, mode="valid")
    first, final = ma[0], ma[-1]
    if final <= first:
        return int(steps[window - 1])
    level = first + 0.9 * (final - first)
    k = int(np.argmax(ma >= level))
    return int(steps[k + window - 1])


def train(*, stage: str, out: str, steps: str | None = None, seed: str = "1", config: Path | None = None,
          quiet: bool = False, command: str = "") -> int:
    """``scripts/train_bv.py``: run ``stage`` (or ``all``: every stage, in order) into ``out`` and print a
    line per stage and the total wall time. The texts ``out``, ``steps`` and ``seed`` are checked here
    (one-line InputError); an ``out`` that cannot be written is one too. Ctrl-C prints how to resume and
    returns :data:`~evoscen_contract.contract.EXIT_INTERRUPTED`."""
    import sys

    from evoscen_contract.contract import EXIT_INTERRUPTED

    from .training_config import training_seed, training_steps

    if not out.strip():
        raise InputError(f"argument --out: expected a non-empty path, got {out!r}")
    steps_n = training_steps("--steps", steps) if steps is not None else None
    seed_n = training_seed("--seed", seed)
    out_dir = Path(out)
    try:
        if out_dir.exists() and not out_dir.is_dir():
            raise InputError(f"--out {out_dir}: exists and is not a directory")
        pipeline = Pipeline(out_dir, seed=seed_n, config_path=config, steps=steps_n, command=command,
                            progress=not quiet)
        results = pipeline.run(list(STAGES) if stage == "all" else [stage])
    except OSError as exc:
        raise InputError(f"--out {out_dir}: {exc.strerror or exc}") from None
    except KeyboardInterrupt:
        print("interrupted: run the same command again to resume from the last checkpoint", file=sys.stderr)
        return EXIT_INTERRUPTED
    for r in results:
        print(f"{r.stage}: {r.policy}.npz, {r.steps} steps in {r.wall_s:.0f} s, "
              f"converged at step {r.steps_to_convergence}, {r.metrics}")
    print(f"total training wall time: {sum(r.wall_s for r in results):.0f} s")
    return 0


class Pipeline:
    """Runs stages into ``out`` (see the module docstring)."""

    def __init__(self, out: Path, *, seed: int, config_path: Path | None = None, steps: int | None = None,
                 command: str = "", progress: bool = True, checkpoint_every: int = 5000) -> None:
        self.out = Path(out)
        self.seed = int(seed)
        self.steps_override = steps
        self.command = command
        self.progress = progress
        self.checkpoint_every = int(checkpoint_every)
        self.out.mkdir(parents=True, exist_ok=True)
        run_file = self.out / "run.json"
        if run_file.is_file():
            started = json.loads(run_file.read_text())
            if started.get("seed") != self.seed:
                raise InputError(f"--out {self.out}: was started with --seed {started.get('seed')}, not {self.seed}; "
                                 f"use the same seed to resume, or another --out")
        else:
            run_file.write_text(json.dumps({"seed": self.seed, "command": command}))
        self.commit = git_commit()
        """The code's commit, taken once when the run starts (recorded in the model cards)."""
        saved = self.out / "training.yaml"
        if saved.is_file():
            # a resumed run keeps the config it started with
            self.config = load_training_config(saved)
        else:
            src = Path(config_path) if config_path is not None else None
            self.config = load_training_config(src)
            from .training_config import default_config_path

            shutil.copyfile(src if src is not None else default_config_path(), saved)
        self._road = None

    @property
    def road(self):
        if self._road is None:
            from evoscen_sim.road.road_model import load_road

            self._road = load_road()
        return self._road

    def stage_steps(self, stage: str) -> int:
        return int(self.steps_override if self.steps_override is not None else getattr(self.config.steps, stage))

    def run(self, stages: list[str]) -> list[StageResult]:
        results = []
        for stage in stages:
            results.append(self.run_stage(stage))
        return results

    # ------------------------------------------------------------------ one stage
    def _make_env(self, stage: str):
        from .environments import CarFollowingEnv, DecisionEnv
        from .lane_change_decision import OBS_DIM
        from .learned import load_actor

        for need in NEEDS[stage]:
            if not (self.out / f"{need}.npz").is_file():
                prev = [s for s, p in POLICY_OF_STAGE.items() if p == need][0]
                raise InputError(f"stage {stage} needs {self.out / (need + '.npz')}: run --stage {prev} first "
                                 f"(or --stage all)")
        if stage == "control":
            return CarFollowingEnv(self.road, self.config)
        controller = load_actor(self.out, "controller.npz", 4)
        frozen = FROZEN_OF_STAGE[stage]
        frozen_actor = load_actor(self.out, f"{frozen}.npz", OBS_DIM) if frozen else None
        return DecisionEnv(self.road, self.config, KIND_OF_STAGE[stage], controller, frozen_actor)

    def run_stage(self, stage: str) -> StageResult:
        import torch

        from .td3 import TD3, ReplayBuffer

        torch.set_num_threads(1)
        policy = POLICY_OF_STAGE[stage]
        sdir = self.out / stage
        done_file = sdir / "done.json"
        if done_file.is_file():
            d = json.loads(done_file.read_text())
            if self.progress:
                print(f"{stage}: already done ({d['steps']} steps), skipped")
            return StageResult(**d)
        sdir.mkdir(parents=True, exist_ok=True)
        env = self._make_env(stage)
        total = self.stage_steps(stage)
        torch_seed, rng, ep_base = stage_seeds(self.seed, stage)
        p = self.config.td3
        agent = TD3(env.state_dim, 1, 1.0, p, torch_seed)
        replay = ReplayBuffer(env.state_dim, 1, max(total, 1))
        t, episode, wall_before, rows, evals = 0, 0, 0.0, [], []
        ckpt = sdir / "checkpoint.pt"
        if ckpt.is_file():
            state = torch.load(ckpt, weights_only=False)
            agent.load_state_dict(state["agent"])
            rng.bit_generator.state = state["rng"]
            t, episode, wall_before, rows = state["t"], state["episode"], state["wall_s"], state["rows"]
            evals = state["evals"]
            replay.load(sdir / "replay.npz")
        eval_every = self.config.env.eval_every_steps
        next_eval = (t // eval_every + 1) * eval_every
        start = time.perf_counter()
        bar = None
        if self.progress:
            from tqdm import tqdm

            bar = tqdm(total=total, initial=t, desc=stage, unit="step", dynamic_ncols=True)
        next_ckpt = (t // self.checkpoint_every + 1) * self.checkpoint_every
        while t < total:
            obs = env.reset(episode_seed(ep_base, episode))
            ep_return, ep_len, extra = 0.0, 0, {"collisions": 0, "lane_changes": 0, "gap_sum": 0.0}
            while True:
                if t < p.start_steps:
                    action = rng.uniform(-1.0, 1.0, size=1)
                else:
                    action = agent.explore(obs, rng)
                next_obs, reward, terminal, truncated, info = env.step(action)
                replay.add(obs, action, next_obs, reward, terminal)
                obs = next_obs
                ep_return += reward
                ep_len += 1
                extra["collisions"] += int(info["collision"])
                extra["lane_changes"] += int(info.get("executed", 0) != 0)
                extra["gap_sum"] += min(info.get("gap_m", 0.0), 1e3)
                t += 1
                if t >= p.start_steps and replay.size >= p.batch_size:
                    agent.train(replay, rng)
                if bar is not None:
                    bar.update(1)
                if terminal or truncated or t >= total:
                    break
            episode += 1
            wall = wall_before + time.perf_counter() - start
            rows.append({"episode": episode, "step": t, "return": ep_return, "length": ep_len,
                         "mean_reward": ep_return / ep_len, "collisions": extra["collisions"],
                         "lane_changes": extra["lane_changes"], "mean_gap_m": extra["gap_sum"] / ep_len,
                         "wall_s": round(wall, 3)})
            if bar is not None:
                recent = [r["mean_reward"] for r in rows[-10:]]
                bar.set_postfix(reward=f"{np.mean(recent):.3f}", episodes=episode)
            if t >= next_eval and t < total:
                evals.append(self._periodic_eval(stage, env, ep_base, agent, t, evals, sdir))
                next_eval += eval_every
            if t >= next_ckpt and t < total:
                self._checkpoint(ckpt, agent, rng, t, episode, wall, rows, evals, replay, sdir)
                next_ckpt += self.checkpoint_every
        if bar is not None:
            bar.close()
        evals.append(self._periodic_eval(stage, env, ep_base, agent, t, evals, sdir))
        wall = wall_before + time.perf_counter() - start
        best = max(evals, key=selection_key)
        shutil.copyfile(sdir / "best.npz", self.out / f"{policy}.npz")
        self._write_curve(sdir, stage, rows, evals)
        metrics = {"selected_step": best["step"], **self.evaluate(stage, env, ep_base)}
        if "settled" in best:
            metrics.update({k: best[k] for k in ("settled_gap_m", "flip_share", "settled")},
                           settled_evaluations=f"{sum(e['settled'] for e in evals)} of {len(evals)}")
        steps_arr = np.array([r["step"] for r in rows])
        ret_arr = np.array([r["mean_reward"] for r in rows])
        result = StageResult(stage=stage, policy=policy, steps=t, wall_s=round(wall, 1),
                             steps_to_convergence=steps_to_convergence(steps_arr, ret_arr), metrics=metrics)
        self._write_card(result)
        done_file.write_text(json.dumps(asdict(result), indent=2))
        for f in (ckpt, sdir / "replay.npz", sdir / "candidate.npz"):
            f.unlink(missing_ok=True)
        return result

    def _periodic_eval(self, stage: str, env, ep_base: int, agent, t: int, evals: list, sdir: Path) -> dict:
        """Evaluate the current actor; keep it as ``best.npz`` when it ranks above every earlier
        one (:func:`selection_key`: with the settling check, settled first, then the return)."""
        from .td3 import NumpyActor, export_actor

        export_actor(agent.actor, sdir / "candidate.npz")
        actor = NumpyActor.load(sdir / "candidate.npz")
        e = {"step": t, "eval_mean_return": self._eval_actor(stage, env, ep_base, actor)["eval_mean_return"]}
        if stage == "control" and self.config.env.control_settling_check:
            e.update(settling_check(actor, self.config, self.road))
        if not evals or selection_key(e) >= max(selection_key(x) for x in evals):
            (sdir / "candidate.npz").replace(sdir / "best.npz")
        return e

    def _checkpoint(self, ckpt: Path, agent, rng, t, episode, wall, rows, evals, replay, sdir: Path) -> None:
        import torch

        replay.save(sdir / "replay.tmp.npz")
        torch.save({"agent": agent.state_dict(), "rng": rng.bit_generator.state, "t": t, "episode": episode,
                    "wall_s": wall, "rows": rows, "evals": evals}, sdir / "checkpoint.tmp.pt")
        (sdir / "replay.tmp.npz").replace(sdir / "replay.npz")
        (sdir / "checkpoint.tmp.pt").replace(ckpt)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, stage: str, env, ep_base: int) -> dict:
        """Final metrics of the exported policy (and, for the controller, the gap KDE plot)."""
        from .td3 import NumpyActor

        actor = NumpyActor.load(self.out / f"{POLICY_OF_STAGE[stage]}.npz")
        metrics = self._eval_actor(stage, env, ep_base, actor)
        gaps = metrics.pop("_gaps", None)
        if gaps is not None:
            np.savetxt(self.out / stage / "eval_gaps_m.csv", gaps, fmt="%.3f", header="gap_m", comments="")
            self._write_gap_kde(gaps)
        return metrics

    def _eval_actor(self, stage: str, env, ep_base: int, actor) -> dict:
        """Deterministic-policy metrics of ``actor`` on the evaluation seeds (disjoint from training's)."""
        n_eps = EVAL_EPISODES["control" if stage == "control" else "decision"]
        gaps, returns, collisions, lane_changes, steps, decisions = [], [], 0, 0, 0, 0
        for e in range(n_eps):
            obs = env.reset(episode_seed(ep_base, e, evaluation=True))
            ret = 0.0
            while True:
                action = actor.forward(obs[None, :])[0]
                obs, r, terminal, truncated, info = env.step(action)
                ret += r
                steps += 1
                collisions += int(info["collision"])
                if stage == "control":
                    if env.t > self.config.env.control_episode_steps // 3 and obs[3] > 0.5:  # after the transient
                        gaps.append(info["gap_m"])
                else:
                    decisions += 1
                    lane_changes += int(info["executed"] != 0)
                if terminal or truncated:
                    break
            returns.append(ret)
        metrics = {"eval_episodes": n_eps, "eval_mean_return": round(float(np.mean(returns)), 4),
                   "eval_collisions": collisions}
        if stage == "control":
            g = np.array(gaps) if gaps else np.array([np.nan])
            metrics.update(mean_gap_m=round(float(g.mean()), 2), gap_p10_m=round(float(np.percentile(g, 10)), 2),
                           gap_p90_m=round(float(np.percentile(g, 90)), 2), _gaps=g)
        else:
            hours = decisions * self.config.env.decision_interval_steps * 0.1 / 3600.0
            metrics.update(eval_lane_changes=lane_changes, lane_changes_per_hour=round(lane_changes / hours, 1))
        return metrics

    # ------------------------------------------------------------------ outputs
    def _write_curve(self, sdir: Path, stage: str, rows: list[dict], evals: list[dict]) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        with (sdir / "curve.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        steps = np.array([r["step"] for r in rows])
        mr = np.array([r["mean_reward"] for r in rows])
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(steps, mr, lw=0.6, alpha=0.4, label="episode")
        if len(mr) >= 10:
            ax.plot(steps[9:], np.convolve(mr, np.ones(10) / 10, mode="valid"), lw=1.5, label="moving mean (10)")
        ax.plot([e["step"] for e in evals], [e["eval_mean_return"] / self._eval_len(stage) for e in evals], "o-",
                ms=3, label="evaluation (deterministic)")
        with (sdir / "eval.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(evals[-1]))
            w.writeheader()
            w.writerows(evals)
        ax.set_xlabel("training step" + (" (simulation steps)" if stage == "control" else " (decisions)"))
        ax.set_ylabel("mean reward per step")
        ax.set_title(f"{stage}: {POLICY_OF_STAGE[stage]}")
        ax.legend()
        fig.tight_layout()
        fig.savefig(sdir / "curve.png", dpi=90)
        plt.close(fig)

    def _eval_len(self, stage: str) -> int:
        """Steps of an evaluation episode without early termination (to plot returns per step)."""
        e = self.config.env
        return e.control_episode_steps if stage == "control" else e.decision_episode_decisions

    def _write_gap_kde(self, gaps: np.ndarray) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from scipy.stats import gaussian_kde

        fig, ax = plt.subplots(figsize=(6, 3.5))
        if gaps.size > 2 and np.ptp(gaps) > 0:
            xs = np.linspace(0.0, max(60.0, float(gaps.max())), 300)
            ax.plot(xs, gaussian_kde(gaps)(xs))
        ax.axvline(self.config.car_following.target_gap_m, ls="--", c="k", label="target gap g")
        ax.set_xlabel("bumper-to-bumper gap (m)")
        ax.set_ylabel("density")
        ax.set_title("car-following controller: gap held in evaluation")
        ax.legend()
        fig.tight_layout()
        fig.savefig(self.out / "control" / "gap_kde.png", dpi=90)
        plt.close(fig)

    def _write_card(self, r: StageResult) -> None:
        cfg: TrainingConfig = self.config
        coeffs = asdict(cfg.car_following) if r.stage == "control" else asdict(cfg.reward)
        frozen = "none (single leader)" if r.stage == "control" else (FROZEN_OF_STAGE[r.stage] or "level-0 traffic")
        lines = [
            f"# Policy `{r.policy}`", "",
            "```yaml",
            f"policy: {r.policy}",
            f"file: {r.policy}.npz",
            f"stage: {r.stage}",
            f"reward: {'car following (method eqs. 6-7)' if r.stage == 'control' else KIND_OF_STAGE[r.stage]}",
            f"surrounding_traffic: {frozen}",
            f"steps: {r.steps}",
            f"seed: {self.seed}",
            f"wall_time_s: {r.wall_s}",
            f"steps_to_convergence: {r.steps_to_convergence}",
            f"git_commit: {self.commit}",
            f"command: {json.dumps(self.command)}",
            "final_metrics:",
            *[f"  {k}: {v}" for k, v in r.metrics.items()],
            "coefficients:",
            *[f"  {k}: {v}" for k, v in coeffs.items()],
            "td3:",
            *[f"  {k}: {v}" for k, v in asdict(cfg.td3).items()],
            "```", "",
            f"Trained by the evoscen level-k pipeline (`evoscen_bv.pipeline`), config `training.yaml` in this "
            f"directory. Curve: `{r.stage}/curve.csv` of the training output.", "",
        ]
        (self.out / f"{r.policy}.md").write_text("\n".join(lines))
