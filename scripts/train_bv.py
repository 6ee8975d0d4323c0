#!/usr/bin/env python3
"""Train the learned background vehicles: the level-k pipeline (docs/method.md §3.3) with TD3.

    python scripts/train_bv.py --stage control|level1|level2|competitive|cooperative|all --out DIR
                               [--steps N] [--seed S] [--config FILE] [--quiet]

Stages run in order (``all``: every stage; a finished stage is skipped, an interrupted one
resumes from its last checkpoint). ``--steps`` overrides every stage's step count from the
training config (default: the shipped ``share/evoscen_bv/config/training.yaml``). Outputs
in DIR: the policies (``controller.npz``, ``level1_mutual.npz``, ``mutual.npz``,
``competitive.npz``, ``cooperative.npz``) with a model card each (``*.md``), the config used
(``training.yaml``), per stage ``curve.csv``/``curve.png``, and ``control/gap_kde.png``.
DIR then works as ``models.learned.policy_dir``. Bad input prints one line ``error: ...``
and exits with status 2.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_OK

STAGE_CHOICES = ("control", "level1", "level2", "competitive", "cooperative", "all")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, status 2
        print(f"error: {message}", file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def _strict_int(text: str, lo: int, hi: int, expected: str) -> int:
    """Plain decimal digits only (``int()`` would also take ``1_000`` and spaces)."""
    body = text[1:] if text[:1] in "+-" else text
    if not body.isascii() or not body.isdigit() or len(body) > 30 or not lo <= int(text) <= hi:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
    return int(text)


def _positive_int(text: str) -> int:
    from evoscen_sim.limits import MAX_TRAINING_STEPS

    return _strict_int(text, 1, MAX_TRAINING_STEPS, f"a positive integer (decimal digits, at most {MAX_TRAINING_STEPS})")


def _seed(text: str) -> int:
    return _strict_int(text, 0, 2**32 - 1, "an integer in [0, 2^32)")


def _out_path(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a non-empty path, got {text!r}")
    return Path(text)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = _Parser(prog="train_bv.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--stage", required=True, choices=STAGE_CHOICES, help="stage to train, or all")
    ap.add_argument("--out", required=True, type=_out_path, help="output directory (policies, curves, model cards)")
    ap.add_argument("--steps", type=_positive_int, help="training steps of every stage run (default: the config's)")
    ap.add_argument("--seed", type=_seed, default=1, help="random seed (default 1)")
    ap.add_argument("--config", type=Path, help="training YAML (default: the shipped one)")
    ap.add_argument("--quiet", action="store_true", help="no progress bars")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_bv.pipeline import Pipeline
    from evoscen_bv.training_config import STAGES
    from evoscen_sim.errors import InputError

    command = "python scripts/train_bv.py " + shlex.join(sys.argv[1:] if argv is None else argv)
    stages = list(STAGES) if args.stage == "all" else [args.stage]
    try:
        if args.out.exists() and not args.out.is_dir():
            raise InputError(f"--out {args.out}: exists and is not a directory")
        pipeline = Pipeline(args.out, seed=args.seed, config_path=args.config, steps=args.steps, command=command,
                            progress=not args.quiet)
        results = pipeline.run(stages)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: --out {args.out}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted: run the same command again to resume from the last checkpoint", file=sys.stderr)
        return EXIT_INTERRUPTED
    for r in results:
        print(f"{r.stage}: {r.policy}.npz, {r.steps} steps in {r.wall_s:.0f} s, "
              f"converged at step {r.steps_to_convergence}, {r.metrics}")
    print(f"total training wall time: {sum(r.wall_s for r in results):.0f} s")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
