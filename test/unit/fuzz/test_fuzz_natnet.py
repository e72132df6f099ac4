"""Fast fuzz corpus for the NatNet depacketizer: no crash, every rejection a located NatNetError.

Inputs come from hypothesis (derandomized: the same few hundred inputs on every run): mutations of
valid packets (the bench fuzzer's seeds and the golden packets of ``test/unit/core/io/data/natnet``),
targeted overwrites of every count/size field position, and raw random bytes. ``euc-ros bench``
runs the long job (hundreds of thousands of inputs) with the same mutators, and it is there that slow
inputs are found: it gives every input a time limit and counts the ones that exceed it as hangs (a
wall-clock bound has no place in a test, which must pass on a loaded machine; a true hang here is
stopped by the test timeout).
"""
from __future__ import annotations

import random
import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from euc_ros.bench.fuzz import VERSIONS, check_natnet, fuzz, mutate_natnet, natnet_frame, natnet_seeds
from euc_ros.core.errors import InputError
from euc_ros.core.io.natnet import FrameOfData, ModelDef, NatNetError, parse_packet

GOLDEN = Path(__file__).resolve().parents[1] / "core" / "io" / "data" / "natnet"
FAST = settings(max_examples=300, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])


def _golden() -> list[tuple[bytes, tuple[int, int]]]:
    out = []
    for f in sorted(GOLDEN.glob("*.bin")):
        tag = f.stem.split("_")[-1]
        out.append((f.read_bytes(), tuple(int(x) for x in tag.split("."))))
    return out


SEEDS = natnet_seeds() + _golden()
RAW = [d for d, _ in SEEDS]


def parse_checked(data: bytes, version) -> object | None:
    """Parse; a rejection must be a NatNetError naming a byte offset inside the packet and a field."""
    try:
        return parse_packet(data, version)
    except NatNetError as exc:
        assert isinstance(exc, InputError)
        assert exc.offset is not None and 0 <= exc.offset <= len(data), (exc.offset, len(data), str(exc))
        assert exc.field, str(exc)
        assert f"byte {exc.offset}" in str(exc)
        return None


def test_seed_corpus_is_valid():
    assert len(SEEDS) > 20
    for data, version in SEEDS:
        assert parse_packet(data, version) is not None
    frame = parse_packet(natnet_frame((4, 1)), (4, 1))
    assert isinstance(frame, FrameOfData) and len(frame.rigid_bodies) == 14


@FAST
@given(index=st.integers(0, len(SEEDS) - 1), rnd=st.randoms(use_true_random=False),
       other_version=st.booleans(), version=st.sampled_from(VERSIONS))
def test_mutated_packets(index, rnd, other_version, version):
    data, v = SEEDS[index]
    parse_checked(mutate_natnet(data, rnd, RAW), version if other_version else v)


@FAST
@given(version=st.sampled_from(VERSIONS[:4]), at=st.integers(0, 10_000),
       value=st.sampled_from([-1, 0, 1, 3, 14, 15, 255, 0x7FFF, 100_000, 100_001, 0x7FFFFFFF, -0x80000000]),
       fix_header=st.booleans())
def test_every_int32_position_overwritten(version, at, value, fix_header):
    """Counts and byte sizes sit at 4-byte fields: overwrite each position with a hostile value."""
    data = bytearray(natnet_frame(version) if at % 2 else _modeldef(version))
    pos = 4 + at % (len(data) - 7)
    struct.pack_into("<i", data, pos, value)
    if fix_header:
        struct.pack_into("<H", data, 2, len(data) - 4)
    parse_checked(bytes(data), version)


def _modeldef(version) -> bytes:
    from euc_ros.bench.fuzz import natnet_modeldef

    return natnet_modeldef(version)


@FAST
@given(data=st.binary(max_size=3000), version=st.sampled_from(VERSIONS))
def test_random_bytes(data, version):
    parse_checked(data, version)


@FAST
@given(message_id=st.integers(0, 0xFFFF), payload=st.binary(max_size=600), version=st.sampled_from(VERSIONS))
def test_any_message_id_with_a_consistent_header(message_id, payload, version):
    parse_checked(struct.pack("<HH", message_id, len(payload)) + payload, version)


def test_truncations_of_a_full_frame_are_all_located():
    """Every prefix of a 14-body 4.1 frame, with the header made consistent, is a located rejection."""
    full = natnet_frame((4, 1))
    for cut in range(4, len(full) - 4):   # the last 4 bytes are the optional end tag
        data = struct.pack("<HH", 7, cut - 4) + full[4:cut]
        assert parse_checked(data, (4, 1)) is None, cut


def test_accepted_mutants_are_well_formed():
    """What parses is a proper message: frames carry only as many bodies as their payload can hold."""
    rng = random.Random(3)
    accepted = 0
    for _ in range(3000):
        data, v = SEEDS[rng.randrange(len(SEEDS))]
        data = mutate_natnet(data, rng, RAW)
        out = parse_checked(data, v)
        if isinstance(out, FrameOfData):
            accepted += 1
            assert len(out.rigid_bodies) * 38 <= len(data)
            assert all(b.position.shape == (3,) and b.quat.shape == (4,) for b in out.rigid_bodies)
        elif isinstance(out, ModelDef):
            assert all(isinstance(k, int) and isinstance(n, str) for k, n in out.rigid_bodies.items())
    assert accepted > 50


@pytest.mark.parametrize("seed", [1, 2])
def test_the_bench_fuzzer_finds_no_failure_on_a_short_run(seed):
    # every input runs (no wall-clock budget); "hang" = an input still parsing after 30 s, a timeout
    r = fuzz("natnet", 4000, seed=seed, time_budget_s=float("inf"), per_input_timeout_s=30.0)
    assert r["inputs"] == 4000
    assert r["crash"] == r["hang"] == r["unclear"] == r["invalid"] == 0, r["failures"][:3]
    assert r["accepted"] > 0 and r["rejected"] > 1000 and r["rejection_classes"] >= 20
    assert sum(r["classes"].values()) == r["rejected"]


def test_rejection_classes_group_by_message_shape():
    out_a = check_natnet(struct.pack("<HH", 77, 0), (4, 1))
    out_b = check_natnet(struct.pack("<HH", 78, 0), (4, 1))
    assert out_a[0] == out_b[0] == "rejected" and out_a[1] == out_b[1]
    assert check_natnet(natnet_frame((3, 0)), (3, 0)) == ("accepted", None)
