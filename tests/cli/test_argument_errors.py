"""A bad command-line argument, in every ``drake-coop`` command: one line naming the argument
and what is allowed, exit code 2 (argparse's own error prints the whole usage first)."""

import argparse

import pytest

from drake_coop.cli import build_parser, main


def _typed_options() -> list[tuple[str, str, str]]:
    """(command, option, type name) of every option converted by int or float."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = []
    for command, p in sub.choices.items():
        for action in p._actions:
            if action.option_strings and action.type in (int, float):
                out.append((command, action.option_strings[-1], action.type.__name__))
    return out


OPTIONS = _typed_options()


def test_the_commands_have_typed_options_to_check():
    assert {c for c, _, _ in OPTIONS} >= {"run", "study", "identify"}


@pytest.mark.parametrize("command, option, kind", OPTIONS,
                         ids=[f"{c} {o}" for c, o, _ in OPTIONS])
def test_a_type_error_is_one_line_naming_the_argument_and_what_is_allowed(capsys, command,
                                                                          option, kind):
    with pytest.raises(SystemExit) as exited:
        main([command, option, "zz"])
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    allowed = {"int": "an integer", "float": "a number"}[kind]
    assert err == [f"drake-coop {command}: error: argument {option}: invalid {kind} value: "
                   f"'zz' (allowed: {allowed}); see drake-coop {command} -h"]


@pytest.mark.parametrize("argv, named", [
    (["plot", "d", "--bogus"], "unrecognized arguments: --bogus"),
    (["stability", "paper", "--out", "o", "--point", "upside"], "argument --point"),
    (["nonsense"], "argument command: invalid choice: 'nonsense'"),
])
def test_other_argument_errors_are_one_line_too(capsys, argv, named):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0] and "usage:" not in err[0]


def test_identify_offers_every_estimator_the_identification_has():
    from drake_coop.cli.parser import IDENTIFY_ESTIMATORS
    from drake_coop.identification.report import ESTIMATORS

    assert tuple(IDENTIFY_ESTIMATORS) == tuple(ESTIMATORS)


def test_identify_refuses_an_unknown_estimator_in_one_line(capsys):
    from drake_coop.cli import main

    with pytest.raises(SystemExit) as exited:        # the command line's exit, code 2
        main(["identify", "paper", "--out", "unused", "--estimator", "ols"])
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--estimator" in err[0] and "didim" in err[0]
