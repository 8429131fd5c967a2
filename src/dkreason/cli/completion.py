"""`dkreason completion bash|zsh`: a shell completion script, written from the declared
parser (cli/parser.py), so every command and option it knows completes, and nothing else.

    eval "$(dkreason completion bash)"    # in ~/.bashrc; zsh: dkreason completion zsh
"""

from __future__ import annotations

import argparse

from .parser import build

ZSH = "autoload -U +X bashcompinit && bashcompinit\n"  # zsh runs bash's completion functions


def _commands(parser: argparse.ArgumentParser) -> dict[str, list[str]]:
    """Each command (and `specs add`-like action) → its option strings."""
    out: dict[str, list[str]] = {}
    for action in parser._actions:  # argparse keeps its subparsers here, and nowhere public
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = sorted(o for a in sub._actions for o in a.option_strings)
                for inner, options in _commands(sub).items():
                    out[name].append(inner)
                    out[f"{name} {inner}"] = options
    return out


def script(shell: str) -> str:
    """The completion script for `shell` (bash or zsh)."""
    commands = _commands(build(None))
    cases = "\n".join(
        f'    "{name}") opts="{" ".join(options)}" ;;' for name, options in commands.items()
    )
    top = " ".join(c for c in commands if " " not in c)
    bash = f"""_dkreason() {{
  local cur="${{COMP_WORDS[COMP_CWORD]}}" cmd="${{COMP_WORDS[1]}}" opts=""
  if [ "$COMP_CWORD" -eq 1 ]; then
    COMPREPLY=($(compgen -W "{top} --help --version" -- "$cur")); return
  fi
  if [ "$COMP_CWORD" -gt 2 ] && [[ "${{COMP_WORDS[2]}}" != -* ]]; then
    cmd="$cmd ${{COMP_WORDS[2]}}"
  fi
  case "$cmd" in
{cases}
  esac
  if [[ "$cur" == -* ]]; then
    COMPREPLY=($(compgen -W "$opts" -- "$cur"))
  else  # an action (specs add) or a file
    local words="" w
    for w in $opts; do [[ "$w" == -* ]] || words="$words $w"; done
    COMPREPLY=($(compgen -W "$words" -- "$cur") $(compgen -f -- "$cur"))
  fi
}}
complete -o filenames -F _dkreason dkreason
"""
    return (ZSH if shell == "zsh" else "") + bash


def completion(args: argparse.Namespace) -> int:
    print(script(args.shell), end="")
    return 0
