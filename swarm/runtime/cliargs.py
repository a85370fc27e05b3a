"""Command-line arguments checked before anything starts.

Every ``swarm`` command builds its parser from :class:`Parser`, whose errors
are one line on stderr ("swarm run: argument --seed: must be ..., got '-3'")
and exit code 2, and takes its numbers through the converters below, which
reject what is out of range with the flag's name and the value given.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import textwrap
import urllib.parse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from formation_swarm.common.checks import SEED_MAX

if TYPE_CHECKING:
    from formation_swarm.protocol.trust import Tls

USAGE_ERROR = 2  # exit code of every rejected command line, as argparse's own


class Formatter(argparse.HelpFormatter):
    """Wraps each paragraph of a description or an epilog to the terminal and
    keeps a block with indented lines (examples, a list) as written."""

    def __init__(self, prog: str, **kwargs: int) -> None:
        super().__init__(prog, **kwargs)
        # A command list's names sit deeper than the options: leave room for them
        # on the help's column rather than putting their help on the next line.
        self._action_max_length = 16

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        blocks = []
        for block in textwrap.dedent(text).strip().split("\n\n"):
            lines = block.splitlines()
            if any(line.startswith(" ") for line in lines):
                blocks.append("\n".join(indent + line for line in lines))
            else:
                blocks.append(textwrap.fill(" ".join(lines), width, initial_indent=indent, subsequent_indent=indent))
        return "\n\n".join(blocks)


class Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage block) and wrapped paragraphs."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", Formatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> NoReturn:
        self.exit(USAGE_ERROR, f"{self.prog}: {message} (see {self.prog} --help)\n")


def integer(low: int, high: int | None = None) -> Callable[[str], int]:
    """A converter for an integer in [low, high]."""
    span = f">= {low}" if high is None else f"in [{low}, {high}]"

    def convert(text: str) -> int:
        try:
            value = int(text, 10)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer {span}, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"must be {span}, got {text!r}")
        return value

    return convert


def seed(text: str) -> int:
    """A run's seed: what numpy's generators and the link layer's drop hash take."""
    try:
        return integer(0, SEED_MAX)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, 2**63 - 1], got {text!r}") from None


port = integer(1, 65535)


def seconds(high: float | None = None) -> Callable[[str], float]:
    """A converter for a finite duration > 0 (and <= high), in seconds."""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value <= 0 or (high is not None and value > high):
            span = "> 0" if high is None else f"in (0, {high:g}]"
            raise argparse.ArgumentTypeError(f"must be a number of seconds {span}, got {text!r}")
        return value

    return convert


def non_negative(text: str) -> float:
    """A converter for a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def rerun_url(text: str) -> str:
    """A Rerun viewer's gRPC address, e.g. rerun+http://127.0.0.1:9876/proxy."""
    schemes = ("rerun", "rerun+http", "rerun+https")
    try:
        parts = urllib.parse.urlsplit(text)
        ok = parts.scheme in schemes and bool(parts.hostname) and parts.port is not None
    except ValueError:  # a port out of range or not a number
        ok = False
    if not ok:
        raise argparse.ArgumentTypeError(f"must be a viewer address like rerun+http://HOST:PORT/proxy, got {text!r}")
    return text


def make_folder(what: str, path: str | Path) -> Path:
    """Create the folder ``path`` (and its parents) now and prove that a file
    can be written in it, so that a bad output folder fails before anything
    runs rather than after. Raises ValueError naming ``what`` (the flag)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path}: is an existing file, not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise ValueError(f"{what} {path}: cannot create a writable folder there ({exc.strerror or exc})") from None
    return path


def add_run_arguments(parser: argparse.ArgumentParser, *, seeds: str | None, stats: str) -> None:
    """``--scenario``, ``--run``, ``--seed`` and ``--stats``, as every role of a run takes them.
    ``seeds`` names what the seed draws (None: no ``--seed``); ``stats`` what ``--stats`` holds."""
    parser.add_argument(
        "--scenario",
        required=True,
        metavar="FILE|NAME",
        help="the scenario: a TOML file or a shipped scenario's name (see swarm scenarios); "
        "the same for every process of the run",
    )
    parser.add_argument(
        "--run",
        required=True,
        metavar="ID",
        help="run id: the same for every process of the run; every key starts with it",
    )
    if seeds is not None:
        parser.add_argument(
            "--seed",
            type=seed,
            default=None,
            metavar="N",
            help=f"random seed of {seeds} (default: the scenario's); the same for every process of the run",
        )
    parser.add_argument("--stats", metavar="FILE", help=f"write {stats} here at exit (JSON)")


def add_tls_arguments(group: argparse._ArgumentGroup) -> None:
    """--tls-ca/--tls-cert/--tls-key: the TLS identity of a router that hosts
    reach on --listen tls/... (swarm run --hosts, swarm doctor); read with :func:`tls`."""
    group.add_argument(
        "--tls-ca", metavar="FILE", help="with --listen tls/...: the CA the hosts check this router against (PEM)"
    )
    group.add_argument(
        "--tls-cert",
        metavar="FILE",
        help="with --listen tls/...: this router's certificate, naming the address the hosts use (PEM)",
    )
    group.add_argument("--tls-key", metavar="FILE", help="with --listen tls/...: this router's private key (PEM)")


def tls(args: argparse.Namespace) -> Tls | None:
    """--tls-ca/--tls-cert/--tls-key as a trust.Tls (all three or none)."""
    from formation_swarm.protocol.trust import Tls

    files = (args.tls_ca, args.tls_cert, args.tls_key)
    if not any(files):
        return None
    if not all(files):
        raise ValueError("--tls-ca, --tls-cert and --tls-key: give all three or none")
    for flag, path in zip(("--tls-ca", "--tls-cert", "--tls-key"), files, strict=True):
        if not Path(path).is_file():
            raise ValueError(f"{flag}: no such file: {path}")
    return Tls(Path(args.tls_ca), Path(args.tls_cert), Path(args.tls_key))
