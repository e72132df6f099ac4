"""A result records what it was made from by content, and refuses data it was not made from."""
from __future__ import annotations

import hashlib

import pytest

from euc_ros.core.io.provenance import InputMismatch, check_inputs, inputs_record, recording_sha256


@pytest.fixture
def files(tmp_path):
    (tmp_path / "session.yaml").write_text("rider:\n  mass: 72\n")
    (tmp_path / "a.csv").write_text("Format Version,1.23\nframe,1\n")
    (tmp_path / "b.csv").write_text("Format Version,1.23\nframe,2\n")
    return tmp_path


def test_the_hash_is_the_contents_sha256(files):
    assert recording_sha256(files / "a.csv") == hashlib.sha256(b"Format Version,1.23\nframe,1\n").hexdigest()


def test_a_bag_is_its_storage_files_not_its_index(files):
    bag = files / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(b"\x89MCAP0\r\n data")
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    before = recording_sha256(bag)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {rebuilt: true}\n")
    assert recording_sha256(bag) == before
    (bag / "bag_0.mcap").write_bytes(b"\x89MCAP0\r\n other")
    assert recording_sha256(bag) != before


def test_the_same_data_under_another_path_is_accepted(files, tmp_path_factory):
    record = inputs_record(files / "session.yaml", [files / "a.csv", files / "b.csv"])
    moved = tmp_path_factory.mktemp("moved")
    (moved / "s.yaml").write_bytes((files / "session.yaml").read_bytes())
    (moved / "take.csv").write_bytes((files / "b.csv").read_bytes())
    assert check_inputs(record, session=moved / "s.yaml", recordings=[moved / "take.csv"], source="r.json") == []


def test_another_session_is_refused_naming_both_files(files):
    record = inputs_record(files / "session.yaml", [files / "a.csv"])
    other = files / "other.yaml"
    other.write_text("rider:\n  mass: 80\n")
    with pytest.raises(InputMismatch) as err:
        check_inputs(record, session=other, recordings=[files / "a.csv"], source="r.json")
    text = str(err.value)
    assert text.startswith("r.json: ") and "other.yaml" in text and "session.yaml" in text and "--force" in text


def test_another_recording_is_refused_naming_it(files):
    record = inputs_record(files / "session.yaml", [files / "a.csv"])
    with pytest.raises(InputMismatch, match="b.csv is not among the recordings it was made from"):
        check_inputs(record, recordings=[files / "a.csv", files / "b.csv"], source="r.json")


def test_force_turns_the_refusal_into_a_warning(files):
    record = inputs_record(files / "session.yaml", [files / "a.csv"])
    warnings = check_inputs(record, recordings=[files / "b.csv"], source="r.json", force=True)
    assert len(warnings) == 1 and "b.csv" in warnings[0] and "--force" in warnings[0]


def test_a_result_without_inputs_cannot_be_checked(files):
    with pytest.raises(InputMismatch, match="records no inputs"):
        check_inputs({}, session=files / "session.yaml", source="old.json")
    assert check_inputs(None, session=files / "session.yaml", source="old.json", force=True)
