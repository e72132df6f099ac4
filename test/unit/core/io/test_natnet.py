"""NatNet depacketizer against golden frames from an independent encoder.

The encoder below is written from the protocol description (packet layouts per version, see
docs/natnet.md), with plain ``struct.pack`` and no code shared with ``euc_ros.core.io.natnet``.
Run this file as a script to rewrite the golden ``.bin`` files under ``data/natnet/``:

    .venv/bin/python test/unit/core/io/test_natnet.py --write-golden

Tolerances: golden values are float32 fields of the packets; the latency is an exact difference of
two integer clock counts divided once by the clock frequency: within half an ulp of 4.5 ms
(4e-19 s); abs 1e-15 s is over 1000 ulps.
"""
from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.errors import InputError
from euc_ros.core.io.natnet import (
    FrameOfData,
    MessageString,
    ModelDef,
    NatNetError,
    Request,
    Response,
    ServerInfo,
    UnrecognizedRequest,
    latency_s,
    parse_packet,
)

GOLDEN_DIR = Path(__file__).parent / "data" / "natnet"
VERSIONS = [(3, 0), (3, 1), (4, 0), (4, 1)]

# ---------------------------------------------------------------------------------------------------------------------
# Independent encoder (protocol description -> bytes)
# ---------------------------------------------------------------------------------------------------------------------


def packet(message_id: int, payload: bytes) -> bytes:
    """Header: uint16 message id, uint16 payload byte count, little endian."""
    return struct.pack("<HH", message_id, len(payload)) + payload


def cstr(text: str) -> bytes:
    return text.encode("utf-8") + b"\x00"


def i32(v: int) -> bytes:
    return struct.pack("<i", v)


def section(version, count: int, body: bytes) -> bytes:
    """A frame section: int32 count, (4.1+) int32 byte count of the body, body."""
    out = i32(count)
    if tuple(version) >= (4, 1):
        out += i32(len(body))
    return out + body


def enc_server_info(name="Motive", app=(3, 1, 0, 0), natnet=(4, 1, 0, 0), freq=10_000_000, port=1511,
                    multicast=False, group=(239, 255, 42, 99), short=False) -> bytes:
    payload = name.encode().ljust(256, b"\x00") + bytes(app) + bytes(natnet)
    if not short:
        payload += struct.pack("<QH?4B", freq, port, multicast, *group)
    return packet(1, payload)


def enc_rb_record(rb_id, pos, quat, err, tracked) -> bytes:
    """Frame rigid body (3.0+): int32 id, float pos[3], float quat[4] (x,y,z,w), float error, int16 params."""
    return struct.pack("<i3f4ffh", rb_id, *pos, *quat, err, 0x01 if tracked else 0x00)


def enc_rb_desc(version, name, rb_id, parent, offset, markers) -> bytes:
    """Rigid-body description: name, id, parent, offset[3], n, positions[n][3], labels[n], (4.0+) names[n]."""
    out = cstr(name) + struct.pack("<ii3f", rb_id, parent, *offset) + i32(len(markers))
    out += b"".join(struct.pack("<3f", *m[0]) for m in markers)
    out += b"".join(i32(m[1]) for m in markers)
    if version[0] >= 4:
        out += b"".join(cstr(m[2]) for m in markers)
    return out


def dataset(version, dtype: int, body: bytes) -> bytes:
    """MODELDEF dataset: int32 type, (4.1+) int32 byte count, body."""
    out = i32(dtype)
    if tuple(version) >= (4, 1):
        out += i32(len(body))
    return out + body


# Known content of the golden MODELDEF.
RIGID_BODIES = {1: ("E", -1, (0.0, 0.1, 0.0)), 2: ("H", -1, (0.0, 0.0, 0.0)), 7: ("TL", 2, (0.01, -0.02, 0.03))}


def enc_modeldef(version) -> bytes:
    ds = []
    ds.append(dataset(version, 0, cstr("all") + i32(3) + cstr("E_1") + cstr("E_2") + cstr("H_1")))
    for rb_id, (name, parent, off) in RIGID_BODIES.items():
        markers = [((0.01 * k, 0.02, -0.01 * k), 100 + k, f"{name}_{k}") for k in range(rb_id % 4 + 1)]
        ds.append(dataset(version, 1, enc_rb_desc(version, name, rb_id, parent, off, markers)))
    bones = b"".join(enc_rb_desc(version, f"bone{k}", (3 << 16) | k, k - 1, (0.0, 0.1 * k, 0.0),
                                 [((0.0, 0.0, 0.0), k, f"bm{k}")]) for k in range(1, 4))
    ds.append(dataset(version, 2, cstr("Skel") + i32(3) + i32(3) + bones))
    fp = (i32(11) + cstr("FP-0001") + struct.pack("<2f", 0.6, 0.4) + struct.pack("<3f", 0.1, 0.0, 0.2)
          + struct.pack("<144f", *np.arange(144.0)) + struct.pack("<12f", *np.arange(12.0))
          + i32(1) + i32(0) + i32(2) + cstr("Fz") + cstr("Mx"))
    ds.append(dataset(version, 3, fp))
    dev = i32(21) + cstr("EMG") + cstr("SN-9") + i32(2) + i32(0) + i32(1) + cstr("ch0")
    ds.append(dataset(version, 4, dev))
    ds.append(dataset(version, 5, cstr("Cam 1") + struct.pack("<3f4f", 1, 2, 3, 0, 0, 0, 1)))
    if tuple(version) >= (4, 1):
        asset = (cstr("Prop") + i32(1) + i32(31)
                 + i32(1) + enc_rb_desc(version, "prop_rb", 32, -1, (0, 0, 0), [((0, 0, 0), 1, "p1")])
                 + i32(2) + b"".join(cstr(f"pm{k}") + struct.pack("<i3ffh", k, 0.1, 0.2, 0.3, 0.014, 0)
                                     for k in range(2)))
        ds.append(dataset(version, 6, asset))
    return packet(5, i32(len(ds)) + b"".join(ds))


# Known content of the golden frame.
FRAME_NUMBER = 123456
BODIES = [  # id, pos, quat xyzw, mean error, tracked
    (1, (0.10, 0.65, -0.02), (0.0, 0.0, 0.0, 1.0), 0.00012, True),
    (2, (0.05, 1.75, 0.01), (0.1, 0.2, 0.3, 0.927362), 0.00031, True),
    (7, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), 0.0, False),
]
SUFFIX = dict(timecode=0x01020304, timecode_sub=5, timestamp=12.345678, mid=1_000_000_000, received=1_000_020_000,
              transmit=1_000_045_000, prec_sec=1_700_000_000, prec_frac=123_456_789, params=0x03)
FREQ = 10_000_000


def enc_frame(version, bodies=BODIES, suffix=SUFFIX, eod=True, frame_number=FRAME_NUMBER) -> bytes:
    v = tuple(version)
    out = i32(frame_number)
    sets = [("all", [(1.0, 2.0, 3.0)] * 5), ("E", [(0.1, 0.2, 0.3)] * 4)]
    out += section(v, len(sets), b"".join(cstr(n) + i32(len(m)) + b"".join(struct.pack("<3f", *p) for p in m)
                                          for n, m in sets))
    out += section(v, 2, struct.pack("<6f", 1, 2, 3, 4, 5, 6))                   # legacy other markers
    out += section(v, len(bodies), b"".join(enc_rb_record(*b) for b in bodies))
    bones = b"".join(enc_rb_record((3 << 16) | k, (k, k, k), (0, 0, 0, 1), 0.001, True) for k in range(1, 4))
    out += section(v, 1, i32(3) + i32(3) + bones)                                # one skeleton, 3 bones
    if v >= (4, 1):                                                              # assets
        asset = (i32(31) + i32(2) + enc_rb_record(32, (1, 1, 1), (0, 0, 0, 1), 0.002, True)
                 + enc_rb_record(33, (2, 2, 2), (0, 0, 0, 1), 0.002, False)
                 + i32(3) + b"".join(struct.pack("<i3ffhf", k, 0.1, 0.2, 0.3, 0.014, 0, 0.0005) for k in range(3)))
        out += section(v, 1, asset)
    labeled = b"".join(struct.pack("<i3ffhf", (1 << 16) | k, 0.1 * k, 0.2, 0.3, 0.014, 0x04, 0.0002)
                       for k in range(6))
    out += section(v, 6, labeled)
    fp = i32(11) + i32(2) + b"".join(i32(3) + struct.pack("<3f", 1.5, 2.5, 3.5) for _ in range(2))
    out += section(v, 1, fp)
    dev = i32(21) + i32(1) + i32(2) + struct.pack("<2f", 0.25, 0.5)
    out += section(v, 1, dev)
    s = suffix
    out += struct.pack("<IIdQQQ", s["timecode"], s["timecode_sub"], s["timestamp"], s["mid"], s["received"],
                       s["transmit"])
    if v >= (4, 1):
        out += struct.pack("<II", s["prec_sec"], s["prec_frac"])
    out += struct.pack("<h", s["params"])
    if eod:
        out += i32(0)
    return packet(7, out)


def golden_files() -> dict[str, bytes]:
    """Name -> bytes of the committed golden packets (see data/natnet/README.md)."""
    files = {"serverinfo_4.1.bin": enc_server_info(), "serverinfo_3.0.bin": enc_server_info(
        natnet=(3, 0, 0, 0), app=(2, 2, 0, 0), freq=3_312_000, multicast=True)}
    for v in VERSIONS:
        tag = f"{v[0]}.{v[1]}"
        files[f"modeldef_{tag}.bin"] = enc_modeldef(v)
        files[f"frame_{tag}.bin"] = enc_frame(v)
    return files


# ---------------------------------------------------------------------------------------------------------------------
# Tests
# ---------------------------------------------------------------------------------------------------------------------

def f32(x) -> np.ndarray:
    return np.asarray(x, dtype=np.float32).astype(float)


@pytest.mark.parametrize("version", VERSIONS)
def test_frame_all_fields(version):
    frame = parse_packet(enc_frame(version), version)
    assert isinstance(frame, FrameOfData)
    assert frame.frame_number == FRAME_NUMBER
    assert [b.id for b in frame.rigid_bodies] == [1, 2, 7]
    for got, (rb_id, pos, quat, err, tracked) in zip(frame.rigid_bodies, BODIES):
        np.testing.assert_array_equal(got.position, f32(pos))
        np.testing.assert_array_equal(got.quat, f32(quat))
        assert got.mean_error == f32(err)
        assert got.tracking_valid is tracked
    assert (frame.timecode, frame.timecode_sub) == (SUFFIX["timecode"], SUFFIX["timecode_sub"])
    assert frame.timestamp == SUFFIX["timestamp"]                    # double: exact
    assert frame.camera_mid_exposure == SUFFIX["mid"]
    assert frame.camera_data_received == SUFFIX["received"]
    assert frame.transmit_timestamp == SUFFIX["transmit"]
    if version >= (4, 1):
        assert (frame.precision_timestamp_sec, frame.precision_timestamp_frac) == (SUFFIX["prec_sec"],
                                                                                   SUFFIX["prec_frac"])
        assert frame.n_assets == 1
    else:
        assert (frame.precision_timestamp_sec, frame.precision_timestamp_frac) == (0, 0)
    assert frame.is_recording and frame.tracked_models_changed
    assert (frame.n_marker_sets, frame.n_skeletons, frame.n_labeled_markers, frame.n_force_plates,
            frame.n_devices) == (2, 1, 6, 1, 1)
    assert frame.receive_time_ns is None


@pytest.mark.parametrize("version", VERSIONS)
def test_frame_without_end_tag_and_flags(version):
    suffix = dict(SUFFIX, params=0x00)
    frame = parse_packet(enc_frame(version, suffix=suffix, eod=False), version)
    assert not frame.is_recording and not frame.tracked_models_changed
    only_recording = parse_packet(enc_frame(version, suffix=dict(SUFFIX, params=0x01)), version)
    assert only_recording.is_recording and not only_recording.tracked_models_changed


def test_frame_with_no_bodies():
    frame = parse_packet(enc_frame((4, 1), bodies=[]), (4, 1))
    assert frame.rigid_bodies == [] and frame.frame_number == FRAME_NUMBER


@pytest.mark.parametrize("version", VERSIONS)
def test_modeldef(version):
    md = parse_packet(enc_modeldef(version), version)
    assert isinstance(md, ModelDef)
    assert md.rigid_bodies == {k: v[0] for k, v in RIGID_BODIES.items()}
    assert md.parents == {k: v[1] for k, v in RIGID_BODIES.items()}
    for k, (_, _, off) in RIGID_BODIES.items():
        np.testing.assert_array_equal(md.offsets[k], f32(off))
    assert md.marker_sets == ["all"]
    assert md.skeletons == {3: "Skel"}
    assert (md.n_force_plates, md.n_devices, md.n_cameras) == (1, 1, 1)
    assert md.assets == ({31: "Prop"} if version >= (4, 1) else {})


def test_server_info_full_and_short():
    si = parse_packet(enc_server_info(), (4, 1))
    assert si == ServerInfo("Motive", (3, 1, 0, 0), (4, 1, 0, 0), 10_000_000, False, "239.255.42.99", 1511)
    assert si.version == (4, 1)
    short = parse_packet(enc_server_info(natnet=(2, 9, 0, 0), short=True), (3, 0))
    assert short.version == (2, 9) and short.high_res_clock_frequency is None and short.data_port is None
    with pytest.raises(NatNetError, match="connection_info"):
        parse_packet(enc_server_info()[:-3][:2] + struct.pack("<H", 276) + enc_server_info()[4:-3], (4, 1))


def test_latency_uses_transmit_minus_mid_exposure():
    frame = parse_packet(enc_frame((4, 1)), (4, 1))
    si = parse_packet(enc_server_info(freq=FREQ), (4, 1))
    # (1_000_045_000 - 1_000_000_000) ticks / 1e7 Hz = 4.5 ms
    assert latency_s(frame, si) == pytest.approx(0.0045, abs=1e-15)
    no_mid = parse_packet(enc_frame((4, 1), suffix=dict(SUFFIX, mid=0)), (4, 1))
    assert np.isnan(latency_s(no_mid, si))
    assert np.isnan(latency_s(frame, parse_packet(enc_server_info(short=True), (4, 1))))
    backwards = parse_packet(enc_frame((4, 1), suffix=dict(SUFFIX, transmit=SUFFIX["mid"] - 1)), (4, 1))
    assert np.isnan(latency_s(backwards, si))


def test_other_messages():
    assert parse_packet(packet(8, cstr("hello")), (4, 1)) == MessageString("hello")
    assert parse_packet(packet(3, i32(-1)), (4, 1)) == Response(-1, None)
    assert parse_packet(packet(3, cstr("Bitstream,4.1")), (4, 1)) == Response(None, "Bitstream,4.1")
    assert parse_packet(packet(100, b""), (4, 1)) == UnrecognizedRequest()
    req = parse_packet(packet(10, b""), (4, 1))
    assert req == Request(10, b"")


@pytest.mark.parametrize("version", VERSIONS)
def test_wrong_version_is_rejected_not_misread(version):
    """A 4.1 frame read as 3.x/4.0 (or the reverse) must fail loudly, not yield wrong poses."""
    other = (4, 0) if version == (4, 1) else (4, 1)
    with pytest.raises(NatNetError):
        parse_packet(enc_frame(other), version)


@pytest.mark.parametrize("version", VERSIONS)
def test_every_truncation_raises_natnet_error(version):
    full = enc_frame(version)
    for cut in range(0, len(full)):
        data = full[:cut]
        with pytest.raises(NatNetError):
            parse_packet(data, version)
        if cut >= 4:   # header rewritten to agree with the shorter payload: the parser must hit the end itself
            consistent = struct.pack("<HH", 7, cut - 4) + full[4:cut]
            if cut - 4 == len(full) - 4 - 4:
                continue   # exactly the frame without its optional end-of-data tag: valid
            with pytest.raises(NatNetError) as info:
                parse_packet(consistent, version)
            assert info.value.offset is not None and info.value.field


@pytest.mark.parametrize("version", VERSIONS)
def test_modeldef_truncations_raise_natnet_error(version):
    full = enc_modeldef(version)
    for cut in range(4, len(full) - 1, 7):
        with pytest.raises(NatNetError):
            parse_packet(struct.pack("<HH", 5, cut - 4) + full[4:cut], version)


@pytest.mark.parametrize("version", VERSIONS)
def test_random_corruption_never_leaks_other_exceptions(version):
    rng = np.random.default_rng(8)
    full = bytearray(enc_frame(version))
    n_errors = 0
    for _ in range(1500):
        data = bytearray(full)
        for pos in rng.integers(4, len(data), size=rng.integers(1, 4)):
            data[pos] = int(rng.integers(0, 256))
        try:
            parse_packet(bytes(data), version)
        except NatNetError:
            n_errors += 1
    assert n_errors > 100     # corruption of counts/sizes is detected, and nothing but NatNetError escaped


def test_named_corruptions():
    v = (4, 1)
    frame = bytearray(enc_frame(v))
    # rigid-body count (after frame number, 2 marker sets, 2 other markers) made negative
    rb_count_at = 4 + 4 + 8 + sum(len(n) + 1 + 4 + 12 * m for n, m in (("all", 5), ("E", 4))) + 8 + 24
    assert struct.unpack_from("<i", frame, rb_count_at)[0] == 3
    bad = bytearray(frame)
    struct.pack_into("<i", bad, rb_count_at, -5)
    with pytest.raises(NatNetError, match="rigid_bodies.count") as info:
        parse_packet(bytes(bad), v)
    assert info.value.offset == rb_count_at and isinstance(info.value, InputError)
    bad = bytearray(frame)
    struct.pack_into("<i", bad, rb_count_at + 4, 3 * 38 + 1)   # byte count disagrees with content
    with pytest.raises(NatNetError, match="declares 115 bytes"):
        parse_packet(bytes(bad), v)
    bad = bytearray(frame)
    struct.pack_into("<i", bad, rb_count_at, 10**9)
    with pytest.raises(NatNetError, match="implausible count"):
        parse_packet(bytes(bad), v)
    with pytest.raises(NatNetError, match="unknown message id 77"):
        parse_packet(packet(77, b""), v)
    with pytest.raises(NatNetError, match="shorter than the 4-byte header"):
        parse_packet(b"\x07\x00", v)
    with pytest.raises(NatNetError, match="not supported"):
        parse_packet(enc_frame(v), (2, 9))
    with pytest.raises(NatNetError, match="unterminated string"):
        parse_packet(packet(5, i32(1) + i32(1) + b"abc"), (4, 0))


def test_later_minor_skips_sections_by_byte_count():
    """4.2+: sections other than rigid bodies are skipped by their byte counts (robust to new fields)."""
    v = (4, 2)
    out = i32(5) + section(v, 1, b"new-marker-set-layout") + section(v, 0, b"")
    out += section(v, 1, enc_rb_record(9, (1, 2, 3), (0, 0, 0, 1), 0.001, True))
    for _ in range(5):   # skeletons, assets, labeled markers, force plates, devices, with unknown content
        out += section(v, 2, b"\x01" * 13)
    out += struct.pack("<IIdQQQII", 0, 0, 1.5, 10, 20, 30, 0, 0) + struct.pack("<h", 0) + i32(0)
    frame = parse_packet(packet(7, out), v)
    assert [b.id for b in frame.rigid_bodies] == [9] and frame.transmit_timestamp == 30


def test_golden_files_match_encoder_and_parse():
    files = golden_files()
    missing = [n for n in files if not (GOLDEN_DIR / n).is_file()]
    assert not missing, f"golden files missing (run this file with --write-golden): {missing}"
    for name, data in files.items():
        assert (GOLDEN_DIR / name).read_bytes() == data, name
    assert parse_packet((GOLDEN_DIR / "serverinfo_3.0.bin").read_bytes()).version == (3, 0)
    for v in VERSIONS:
        tag = f"{v[0]}.{v[1]}"
        frame = parse_packet((GOLDEN_DIR / f"frame_{tag}.bin").read_bytes(), v)
        assert [b.tracking_valid for b in frame.rigid_bodies] == [True, True, False]
        md = parse_packet((GOLDEN_DIR / f"modeldef_{tag}.bin").read_bytes(), v)
        assert md.rigid_bodies[7] == "TL"


if __name__ == "__main__":
    if "--write-golden" in sys.argv:
        GOLDEN_DIR.mkdir(parents=True, exist_ok=True)
        for fname, content in golden_files().items():
            (GOLDEN_DIR / fname).write_bytes(content)
            print(f"wrote {GOLDEN_DIR / fname} ({len(content)} bytes)")
