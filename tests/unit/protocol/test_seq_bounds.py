"""A message's seq and tick: the range docs/protocol/messages.md gives is the
codec's (MAX_TICK, both ends included), the encoder refuses what every decoder
refuses, and a receiver takes seq 0 though our senders count from 1."""

from __future__ import annotations

import re

import msgpack
import pytest

from formation_swarm.protocol.codec import MAX_TICK, DecodeError
from formation_swarm.protocol.messages import Command
from tests.helpers import ROOT
from world.commands import NEVER

DOC = ROOT / "docs" / "protocol" / "messages.md"


def command(seq: object = 1, tick: object = 1) -> Command:
    return Command(sender=2, seq=seq, tick=tick, left_mps=0.1, right_mps=0.1, formation=0, done=False)  # type: ignore[arg-type]


def test_the_docs_seq_range_is_the_codecs() -> None:
    text = DOC.read_text()
    ranges = set(re.findall(r"^\| 3 \| seq \| `int 0\.\.2\^(\d+)` \|", text, re.M))
    assert ranges == {"53"}  # every message's table says the same
    assert 2 ** int(ranges.pop()) == MAX_TICK == 9_007_199_254_740_992
    assert "| `MAX_TICK` | `2^53` |" in text


@pytest.mark.parametrize(("seq", "tick"), [(0, 0), (MAX_TICK, MAX_TICK), (1, MAX_TICK), (MAX_TICK, 0)])
def test_both_ends_are_written_and_read(seq: int, tick: int) -> None:
    got = Command.from_bytes(command(seq, tick).to_bytes())
    assert (got.seq, got.tick) == (seq, tick)


@pytest.mark.parametrize("field", ["seq", "tick"])
@pytest.mark.parametrize("bad", [-1, MAX_TICK + 1, True, 2.0])
def test_the_encoder_refuses_what_every_decoder_refuses(field: str, bad: object) -> None:
    with pytest.raises(ValueError, match=rf"^Command\.{field} must be an int in \[0, 2\^53\], got {bad!r}$"):
        command(**{field: bad}).to_bytes()
    # What it refuses to write, the decoder refuses to read.
    values = msgpack.unpackb(command().to_bytes())
    values[3 if field == "seq" else 4] = bad
    with pytest.raises(DecodeError, match=rf"(out of range|wrong type): {field}"):
        Command.from_bytes(msgpack.packb(values))


def test_a_first_command_of_seq_0_at_tick_0_is_newer_than_none() -> None:
    assert NEVER < (0, 0)  # the world's gate starts below every (tick, seq) a decoder takes
