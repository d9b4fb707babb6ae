"""The ``sigma-des`` parser with every subcommand's arguments, for sphinx-argparse.

``sigma_des.cli`` adds a subcommand's arguments only when that subcommand is chosen
(so ``--help`` starts without the heavy imports); the reference wants them all, so
this builds the same parser with each command's arguments added.
"""

from __future__ import annotations

import argparse

from sigma_des import cli

__all__ = ["parser"]


def parser() -> argparse.ArgumentParser:
    """``sigma-des``'s parser, every subcommand with its own arguments."""
    p = cli._parser([])
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    for name, cmd in cli.COMMANDS.items():
        sp = sub.choices[name]
        if cmd.scenario:
            cli._scenario_args(sp)
        cli._function(cmd.args)(sp)
    return p
