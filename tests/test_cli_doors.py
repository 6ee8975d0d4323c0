"""The scripts' shared argument module (evoscen.cli): the same option checks, the same exit statuses and
the score a door ranks by in its --help."""

from __future__ import annotations

import pytest

from evoscen import cli
from evoscen_sim.errors import HostFault, InputError, PluginFault


def test_checks_are_one_line_errors_naming_the_option():
    assert cli.positive_int("--seeds", " 12 ") == 12 and cli.positive_int("--first-seed", "0", 0) == 0
    for text in ("0", "-3", "1.5", "many"):
        with pytest.raises(InputError, match=rf"^--seeds = '{text}': expected an integer >= 1$"):
            cli.positive_int("--seeds", text)
    assert cli.names("--suts", "mobil, nilsson") == ["mobil", "nilsson"]
    with pytest.raises(InputError, match=r"^--suts 'mobil,mobil': expected distinct comma-separated SUT models$"):
        cli.names("--suts", "mobil,mobil", "SUT models")
    blocks = cli.seed_blocks("--seed-blocks", "10:19,30:34")
    assert [(b.first, b.last) for b in blocks] == [(10, 19), (30, 34)]


def test_the_parser_names_the_score_it_ranks_by():
    p = cli.parser("x.py", "First paragraph.\n\nMore.", ranks_by="D")
    cli.add_out(p, "runs/x")
    cli.add_seeds(p, count=5, first=100)
    cli.add_jobs(p, default=2)
    text = p.format_help()
    assert "First paragraph." in text and "More." not in text
    assert "Ranks by: D, the comparative score" in text and "docs/evaluation.md §10" in text
    args = p.parse_args([])
    assert (str(args.out), args.seeds, args.first_seed, args.jobs) == ("runs/x", "5", "100", "2")
    assert "Ranks by" not in cli.parser("y.py", "Doc.").format_help()
    with pytest.raises(ValueError, match="ranks_by 'score'"):
        cli.parser("z.py", "Doc.", ranks_by="score")


def test_run_gives_the_exit_status_of_each_ending(capsys):
    def raising(exc):
        def work():
            raise exc
        return work

    assert cli.run(lambda: None) == 0 and cli.run(lambda: 4) == 4
    assert cli.run(raising(InputError("--steps = 'x': expected an integer >= 1"))) == 2
    assert capsys.readouterr().err == "error: --steps = 'x': expected an integer >= 1\n"
    import errno

    fault = HostFault.of(OSError(errno.ENOSPC, "No space left on device"), "/x/bag_0.mcap")
    assert cli.run(raising(fault)) == 5
    assert capsys.readouterr().err == f"error: {fault.line()}\n" and "/x/bag_0.mcap" in fault.line()
    assert cli.run(raising(PluginFault("sut model 'my_sut' raised in act: ValueError: boom", model="my_sut", role="sut"))) == 3
    assert capsys.readouterr().err == "error: sut model 'my_sut' raised in act: ValueError: boom\n"
    assert cli.run(raising(KeyboardInterrupt())) == 130
    assert capsys.readouterr().err.endswith("interrupted\n")


def test_one_line_errors_make_a_bad_command_line_one_error_line(capsys):
    p = cli.one_line_errors(cli.parser("x.py", "Doc."))
    p.add_argument("--steps", type=int, required=True)
    assert cli.run(lambda: p.parse_args(["--steps", "3", "--frobnicate"])) == 2
    assert capsys.readouterr().err == "error: unrecognized arguments: --frobnicate\n"
    assert cli.run(lambda: p.parse_args(["--steps", "x"])) == 2
    assert capsys.readouterr().err == "error: argument --steps: invalid int value: 'x'\n"
    assert cli.run(lambda: p.parse_args([])) == 2
    assert capsys.readouterr().err == "error: the following arguments are required: --steps\n"
    assert p.parse_args(["--steps", "3"]).steps == 3
