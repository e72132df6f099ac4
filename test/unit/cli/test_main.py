"""The euc-ros dispatcher: every command has --help, errors are exit code 2."""
import pytest

from euc_ros.cli.main import COMMANDS, main


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert "usage: euc-ros " + command in capsys.readouterr().out


def test_top_level_help_lists_commands(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert all(c in out for c in COMMANDS)


def test_unknown_command_is_an_error():
    with pytest.raises(SystemExit) as exc:
        main(["frobnicate"])
    assert exc.value.code == 2


def test_user_error_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "session.yaml"
    bad.write_text("world_up: y\nrate_hz: 120\nrider: {}\neuc: {}\nextra: 1\n")
    assert main(["identify", str(bad), str(tmp_path / "x.csv"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "session.yaml" in err[0] and "extra" in err[0]
