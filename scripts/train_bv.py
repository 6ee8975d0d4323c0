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

import shlex
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli

STAGE_CHOICES = ("control", "level1", "level2", "competitive", "cooperative", "all")


def parse_args(argv: list[str] | None):
    p = cli.one_line_errors(cli.parser("train_bv.py", __doc__))
    p.add_argument("--stage", required=True, choices=STAGE_CHOICES, help="stage to train, or all")
    p.add_argument("--out", required=True, help="output directory (policies, curves, model cards)")
    p.add_argument("--steps", help="training steps of every stage run (default: the config's)")
    p.add_argument("--seed", default="1", help="random seed (default 1)")
    p.add_argument("--config", type=Path, help="training YAML (default: the shipped one)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    command = "python scripts/train_bv.py " + shlex.join(sys.argv[1:] if argv is None else argv)

    def work() -> int:
        from evoscen_bv.pipeline import train

        return train(**vars(parse_args(argv)), command=command)

    return cli.run(work)


if __name__ == "__main__":
    sys.exit(main())
