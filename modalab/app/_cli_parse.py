"""Parsing the command line: unknown commands and options are one line naming the closest valid one (exit 2),
never the usage block."""
from __future__ import annotations

import difflib
import re
import sys


def _closest_option(parser, arg: str) -> str | None:
    """The option of ``parser`` closest to the unknown ``arg`` (``--exp_end`` -> ``--exp-end``), or None."""

    opts = [o for o in parser._option_string_actions if o.startswith("--")]
    key = arg.split("=", 1)[0]
    norm = {o.replace("_", "-").lower(): o for o in opts}
    if key.replace("_", "-").lower() in norm:
        return norm[key.replace("_", "-").lower()]
    m = difflib.get_close_matches(key, opts, n=1, cutoff=0.6)
    return m[0] if m else None


def _n_global(argv) -> int:
    """How many leading arguments are the top-level options (-v, --verbose, -vv)."""
    n = 0
    while n < len(argv) and argv[n] in ("-v", "-vv", "--verbose"):
        n += 1
    return n


_CHOICE = re.compile(r"invalid choice: '([^']*)' \(choose from (.*)\)$")


def _one_line_error(p):
    """``p.error``: argparse's own errors (a missing required argument, an invalid choice or number) as one line
    with what to do, never the usage block; an invalid choice names the closest valid one (exit code 2)."""

    def error(message):
        m = _CHOICE.search(message)
        if m:
            choices = [c.strip().strip("'") for c in m.group(2).split(",")]
            best = difflib.get_close_matches(m.group(1), choices, n=1, cutoff=0.5)
            if best:
                bad = f"invalid choice: '{m.group(1)}'"
                message = message.replace(bad, f"{bad} (did you mean {best[0]!r}?)", 1)
        print(f"{p.prog}: error: {message}; see '{p.prog} --help'", file=sys.stderr)
        raise SystemExit(2)

    return error


def _all_parsers(parser):
    yield parser
    for act in getattr(parser, "_subparsers", None) and parser._subparsers._group_actions or ():
        for sp in act.choices.values():
            yield from _all_parsers(sp)


def parse_args(parser, args):
    """``parse_args`` whose unknown options are one line naming the command, each unknown option and the closest
    valid option of that command (exit code 2); argparse's other errors are one line too."""
    for p in _all_parsers(parser):
        p.error = _one_line_error(p)
    argv = list(sys.argv[1:] if args is None else args)
    first = next((x for x in argv if not x.startswith("-")), None)
    commands = parser._subparsers._group_actions[0].choices if parser._subparsers else {}
    if first is not None and commands and first not in commands and argv.index(first) == _n_global(argv):
        best = difflib.get_close_matches(first, list(commands), n=1, cutoff=0.5)
        print(f"modalab: error: unknown command {first!r}" + (f" (did you mean {best[0]}?)" if best else "")
              + f"; the commands are {', '.join(commands)}; see 'modalab --help'", file=sys.stderr)
        raise SystemExit(2)
    a, extra = parser.parse_known_args(args)
    if not extra:
        return parser.parse_args(args)          # the one parse (a wrapped parse_args sees it)
    cmd = getattr(a, "command", None)
    sp = parser._subparsers._group_actions[0].choices.get(cmd) if cmd and parser._subparsers else None
    target = sp or parser
    parts = []
    for x in extra:
        if x.startswith("-") and len(x) > 1:
            best = _closest_option(target, x)
            parts.append(f"{x} (did you mean {best}?)" if best else x)
        else:
            parts.append(x)
    hint = f"see 'modalab {cmd} --help'" if cmd else "see 'modalab --help'"
    print(f"modalab{' ' + cmd if cmd else ''}: error: unrecognized argument(s): {', '.join(parts)}; {hint}",
          file=sys.stderr)
    raise SystemExit(2)
