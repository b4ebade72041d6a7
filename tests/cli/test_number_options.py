"""Every number option of every command refuses NaN and the infinities (issue 46: --max-joint-drift
nan passed click's range check, as NaN passes every comparison)."""

import click
import pytest

from cli_helpers import assert_user_error, cli
from skinsynth.cli.main import main
from skinsynth.cli.options import FiniteFloat, FiniteFloatRange

NUMBER_OPTIONS = [(name, param.opts[0]) for name, command in sorted(main.commands.items()) for param in command.params
                  if isinstance(param, click.Option) and isinstance(param.type, click.types.FloatParamType)]


def test_every_number_option_takes_a_finite_type():
    assert len(NUMBER_OPTIONS) >= 25  # the commands' float options, all of them
    plain = [f"{name} {option}" for name, command in main.commands.items() for param in command.params
             for option in param.opts[:1]
             if isinstance(param.type, click.types.FloatParamType)
             and not isinstance(param.type, (FiniteFloat, FiniteFloatRange))]
    assert plain == []


@pytest.mark.parametrize("name, option", NUMBER_OPTIONS)
def test_a_number_option_refuses_nan_and_the_infinities(name, option, tmp_path):
    for value in ("nan", "inf", "-inf"):
        assert_user_error(cli(name, option, value), f"'{option}'", folder=tmp_path)
