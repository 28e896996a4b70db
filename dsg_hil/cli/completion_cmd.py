"""``dsg-hil completion bash``: a bash completion script for dsg-hil (commands, their options, file names)."""

from __future__ import annotations

import argparse
import importlib
import shlex

from . import COMMANDS, command_help

__all__ = ["add_subparser", "bash_script", "command_options"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "completion", help=command_help("completion"),
        description="Print a bash completion script for dsg-hil: commands, each command's options, and file "
                    "names for the rest. Use it with 'source <(dsg-hil completion bash)' (e.g. in ~/.bashrc) or "
                    "save it as ~/.local/share/bash-completion/completions/dsg-hil; zsh: run 'autoload "
                    "bashcompinit && bashcompinit' first.")
    parser.add_argument("shell", choices=("bash",), help="the shell (bash; zsh through bashcompinit)")
    parser.set_defaults(func=_do_completion)


def command_options() -> dict[str, list[str]]:
    """Every command and its long options, read from the commands' own parsers (so they cannot drift)."""
    sub = argparse.ArgumentParser(prog="dsg-hil").add_subparsers()
    for module, _ in COMMANDS.values():
        importlib.import_module(f".{module}", __package__).add_subparser(sub)
    return {name: sorted({option for action in parser._actions for option in action.option_strings
                          if option.startswith("--")} | {"--debug"})
            for name, parser in sub.choices.items()}


def bash_script(options: dict[str, list[str]]) -> str:
    """The completion function ``_dsg_hil`` and its ``complete`` line."""
    cases = "\n".join(f"        {name}) opts={shlex.quote(' '.join(opts))} ;;" for name, opts in options.items())
    return f"""# bash completion for dsg-hil (dsg-hil completion bash)
_dsg_hil() {{
    local cur=${{COMP_WORDS[COMP_CWORD]}} opts
    if [[ $COMP_CWORD -eq 1 ]]; then
        COMPREPLY=($(compgen -W {shlex.quote(' '.join([*options, '--help', '--version', '--debug']))} -- "$cur"))
        return
    fi
    case ${{COMP_WORDS[1]}} in
{cases}
        *) opts="" ;;
    esac
    if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W "$opts --help" -- "$cur"))
    else
        COMPREPLY=($(compgen -f -- "$cur"))
    fi
}}
complete -o filenames -F _dsg_hil dsg-hil
"""


def _do_completion(args: argparse.Namespace) -> int:
    print(bash_script(command_options()), end="")
    return 0
