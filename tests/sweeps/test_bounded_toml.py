"""A sweep or --config file is read within its declared limits: a regular file of bounded size,
bounded nesting and key length, refused in one line before it is parsed; an empty one is refused."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading

import pytest

from rmac_mj import constraints
from rmac_mj.cli import main
from rmac_mj.errors import EXIT_BAD_INPUT
from rmac_mj.sweeps import bounded_toml, sweep_file

DEEP = 100_000


def _run(capsys, *args) -> tuple[int, list[str]]:
    code = main([str(a) for a in args])
    return code, [line for line in capsys.readouterr().err.splitlines() if line.strip()]


@pytest.mark.parametrize(
    "name, text, limit",
    [
        ("nested_tables", "a = " + "{b = " * DEEP + "1" + "}" * DEEP, constraints.CONFIG_NESTING),
        ("nested_arrays", "a = " + "[" * DEEP + "1" + "]" * DEEP, constraints.CONFIG_NESTING),
        (
            "dotted_key",
            "[protocol]\n" + ".".join(["a"] * 200_000) + " = 1",
            constraints.CONFIG_KEY_LENGTH,
        ),
        ("quoted_key", '[protocol]\n"' + "a." * 200_000 + 'a" = 1', constraints.CONFIG_KEY_LENGTH),
        (
            "table_header",
            "[" + ".".join(["t"] * 200_000) + "]\nk = 1",
            constraints.CONFIG_KEY_LENGTH,
        ),
        (
            "too_large",
            "# " + "x" * constraints.CONFIG_FILE_BYTES.value,
            constraints.CONFIG_FILE_BYTES,
        ),
    ],
)
@pytest.mark.parametrize("command", ["sweep", "reproduce"])
def test_a_hostile_file_is_refused_in_one_line_before_it_is_parsed(
    tmp_path, capsys, monkeypatch, name, text, limit, command
):
    def no_parse(*args, **kwargs):
        raise AssertionError("parsed")

    monkeypatch.setattr(bounded_toml.tomllib, "loads", no_parse)
    path = tmp_path / f"{name}.toml"
    path.write_text(text + "\n")
    args = [path] if command == "sweep" else ["--config", path]
    code, lines = _run(capsys, command, *args, "--out", tmp_path / "out")
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert f"must be at most {limit.value} ({limit.reason})" in lines[0]
    assert len(lines[0]) < 500  # the key is not echoed
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text", ["", "\n\n# only a comment\n"])
def test_an_empty_sweep_or_config_file_is_refused(tmp_path, capsys, text):
    path = tmp_path / "empty.toml"
    path.write_text(text)
    for args in (["sweep", path], ["reproduce", "--config", path]):
        code, lines = _run(capsys, *args, "--out", tmp_path / "out")
        assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
        assert f"{path}: holds nothing" in lines[0]
    assert not (tmp_path / "out").exists()


def test_a_pipe_is_refused_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    refusals = []

    def read():
        try:
            sweep_file.read_toml(fifo)
        except sweep_file.SweepFileError as error:
            refusals.append(str(error))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout=30)
    assert refusals and "not a regular file" in refusals[0], refusals


def test_config_from_dev_zero_is_refused_under_a_memory_limit(tmp_path):
    """Read without limit, /dev/zero filled the machine's memory; under ulimit -v it is refused."""
    script = textwrap.dedent(
        f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))
        from rmac_mj.cli import main
        sys.exit(main(["reproduce", "--config", "/dev/zero", "--out", {str(tmp_path / "out")!r}]))
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert result.returncode == EXIT_BAD_INPUT, result.stderr
    assert "/dev/zero: is a device, pipe or socket, not a regular file" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_the_measure_tells_keys_from_strings_and_comments(tmp_path):
    text = textwrap.dedent(
        """\
        # comment [[[[ {{{{
        a = "[[[[{{{{\\\\\\" [[" # x [[[[
        b = '[[[[\\'
        c = \"\"\"
        [[[[ \\\"\"\" {{{ ""
        \"\"\"\"
        d = '''[[[[
        '''''
        "e.f".g . h = [[1, 2], [3, {x.y.z = 1, w = [1]}]]
        [t."u.v".w]
        k = 1
        [[arr.of]]
        m = { n = { o = { p = 1 } } }
        n = [
          [ # c [[[[
           1,
          ],
        ]
        """
    )
    bounded_toml.tomllib.loads(text)  # valid TOML
    shape = bounded_toml.measure(text)
    assert (shape.nesting, shape.nesting_line) == (4, 9)
    assert (shape.key_length, shape.key_length_line) == (len('"e.f".g . h'), 9)


def test_a_sweep_index_that_is_a_device_is_a_damaged_sweep(tmp_path, capsys):
    path = tmp_path / "one.toml"
    path.write_text('[protocol]\nalgorithms = ["s-ac"]\nexperiments = 1\ntrials = 1\n')
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.json").symlink_to("/dev/zero")
    code, lines = _run(capsys, "sweep", path, "--resume", "--no-optimal", "--out", out)
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert "sweep.json" in lines[0]  # never read: no sweep to resume
