"""What every command shows in a terminal and writes to a log.

Each command runs twice on tiny inputs: in a pseudo-terminal (a child process on a ``pty``,
its screen rebuilt by the terminal emulator ``pyte``), and with stdout and stderr sent to a
file. In the terminal, the last line on screen names what the command wrote and no progress
bar is left on screen (a bar ends at 100 % and is erased); in the file, there are no blank
lines and no control codes, every stage line reads "k/N: what …" and the last line again names
the outputs.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pytest

pyte = pytest.importorskip("pyte")

SRC = Path(__import__("shprobe").__file__).resolve().parents[1]
COLS, ROWS = 400, 48
BAR = re.compile(r"[━╸╺]")  # rich's bar glyphs
CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")  # anything but \t and \n


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A tiny probe, a tiny mesh, a grey-ball photo and an H-basis bake, made here."""
    import trimesh

    from shprobe.lighting.projection import project
    from shprobe.probes.env import Env
    from shprobe.probes.images import write_image
    from shprobe.scene import Camera, render

    d = tmp_path_factory.mktemp("terminal-data")
    rng = np.random.default_rng(7)
    rad = (rng.random((16, 32, 3)) + 0.2).astype(np.float32)
    rad[:4] += 3.0  # a bright sky
    write_image(d / "probe.hdr", rad)
    trimesh.creation.icosphere(subdivisions=1).export(d / "ball.obj")
    L = project(Env(rad, "latlong"), 2)
    ball = render(None, L, Camera(40, 40, "orthographic"), albedo=0.5)
    write_image(d / "ball.exr", ball.image)
    from shprobe.cli.main import main

    assert main(["-q", "hbasis", "bake", str(d / "ball.obj"), str(d / "probe.hdr"), "-o",
                 str(d / "bake.npz")]) == 0
    return d


#: name → (arguments with {d} the data and {o} the output folder, what the last line names)
COMMANDS = {
    "demo": (["demo", "--out", "{o}/demo", "--size", "32x16"], "5 files in {o}/demo"),
    "prefilter": (["prefilter", "{d}/probe.hdr", "--format", "json", "-o", "{o}/c.json"],
                  "{o}/c.json"),
    "irradiance": (["irradiance", "{d}/probe.hdr", "--size", "16x8", "-o", "{o}/e.png"],
                   "{o}/e.png"),
    "irradiance-brute": (["irradiance", "{d}/probe.hdr", "--method", "brute", "--size",
                          "16x8", "-o", "{o}/b.exr"], "{o}/b.exr"),
    "render": (["render", "{d}/probe.hdr", "--size", "24x24", "-o", "{o}/r.png"],
               "{o}/r.png"),
    "basis-images": (["basis-images", "--sphere", "--size", "16x16", "-o", "{o}/basis"],
                     "19 files in {o}/basis"),
    "edit": (["edit", "--preset", "grace", "--scale-band", "2=0.5", "-o", "{o}/ed.json"],
             "{o}/ed.json"),
    "export": (["export", "--preset", "grace", "--format", "glsl", "-o", "{o}/x.glsl"],
               "{o}/x.glsl"),
    "window": (["window", "--preset", "grace", "-o", "{o}/w.json"], "{o}/w.json"),
    "hbasis-study": (["hbasis", "study", "--signals", "20", "-o", "{o}/study"],
                     "{o}/study/hbasis_study.md, {o}/study/hbasis_study.csv"),
    "hbasis-bake": (["hbasis", "bake", "{d}/ball.obj", "{d}/probe.hdr", "-o", "{o}/h.npz"],
                    "{o}/h.npz"),
    "hbasis-render": (["hbasis", "render", "{d}/ball.obj", "{d}/bake.npz", "--size", "16",
                       "-o", "{o}/h.png"], "{o}/h.png"),
    "fit": (["fit", "grey-ball", "{d}/ball.exr", "--albedo", "0.5", "-F", "json", "-o",
             "{o}/f.json", "--report", "{o}/f.png"], "{o}/f.json, {o}/f.png"),
    "report": (["report", "{d}/probe.hdr", "--map-size", "4", "--render-size", "16", "-o",
                "{o}/r.html"], "{o}/r.html"),
}


def _args(name: str, d: Path, o: Path) -> tuple[list[str], str]:
    args, names = COMMANDS[name]
    return [a.format(d=d, o=o) for a in args], names.format(d=d, o=o)


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NO_COLOR", "FORCE_COLOR", "TTY_COMPATIBLE", "COLUMNS", "LINES")}
    env.update(PYTHONPATH=os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")]),
               TERM="xterm-256color")
    return env


def run_in_terminal(args: list[str]) -> tuple[int, bytes]:
    """Run ``shprobe ARGS`` with stdout and stderr on a pseudo-terminal of COLS × ROWS; its
    return code and everything it drew."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "shprobe", *args], stdin=subprocess.DEVNULL,
                            stdout=slave, stderr=slave, env=_env(), close_fds=True)
    os.close(slave)
    chunks = []
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], 0.1)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the child closed its side
                break
            if not chunk:
                break
            chunks.append(chunk)
        elif proc.poll() is not None:
            break
    rc = proc.wait(timeout=30)
    os.close(master)
    return rc, b"".join(chunks)


def run_here_in_terminal(args: list[str], monkeypatch) -> tuple[int, bytes]:
    """Run ``shprobe ARGS`` in this process with stdout and stderr on a pseudo-terminal (the
    same reporter and bar as a child's, without a child's start-up)."""
    import threading

    from shprobe.cli.main import main

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
    chunks: list[bytes] = []

    def read() -> None:
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the writing side is closed
                return
            if not chunk:
                return
            chunks.append(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    with open(slave, "w", encoding="utf-8", closefd=True) as tty:
        monkeypatch.setattr(sys, "stdout", tty)
        monkeypatch.setattr(sys, "stderr", tty)
        rc = main(args)
        tty.flush()
        monkeypatch.undo()
    reader.join(timeout=30)
    os.close(master)
    return rc, b"".join(chunks)


def screen_of(raw: bytes) -> list[str]:
    """The lines left on the terminal's screen, as the emulator shows them."""
    screen = pyte.Screen(COLS, ROWS)
    stream = pyte.ByteStream(screen)
    stream.feed(raw.replace(b"\n", b"\r\n").replace(b"\r\r\n", b"\r\n"))
    lines = [ln.rstrip() for ln in screen.display]
    while lines and not lines[-1]:
        lines.pop()
    return lines


def frames_of(raw: bytes) -> str:
    """Everything drawn, control sequences removed (the bars as they were shown)."""
    return re.sub(rb"\x1b\[[0-9;?]*[A-Za-z]", b"", raw).decode("utf-8", "replace")


@pytest.mark.parametrize("name", list(COMMANDS))
def test_in_a_terminal(name, data, tmp_path, monkeypatch):
    args, names = _args(name, data, tmp_path)
    rc, raw = run_here_in_terminal(args, monkeypatch)
    lines = screen_of(raw)
    assert rc == 0, "\n".join(lines)
    assert lines and lines[-1].startswith(f"wrote {names}"), "\n".join(lines)
    left = [ln for ln in lines if BAR.search(ln) or re.search(r"\d+ %.*ETA|…$", ln)]
    assert not left, f"a bar was left on screen: {left}"
    drawn = frames_of(raw)
    for k, n in re.findall(r"(\d+)/(\d+): ", drawn):  # stages are numbered k of N
        assert 1 <= int(k) <= int(n)


def test_a_long_stage_shows_a_bar_that_ends_at_100(data, tmp_path):
    """In a child process on a pseudo-terminal, the brute-force map counts its normal–sample
    products: the terminal shows a moving bar with a percentage, its last frame is 100 %,
    and the screen ends with the closing line."""
    args = ["irradiance", str(data / "probe.hdr"), "--method", "brute", "--size", "512x256",
            "-o", str(tmp_path / "b.exr")]
    rc, raw = run_in_terminal(args)
    assert rc == 0
    drawn = frames_of(raw)
    pct = [int(p) for p in re.findall(r"exact irradiance at 131,072 normals \(brute force\)"
                                      r"\s+[━╸╺ ]*\s*(\d+) %", drawn)]
    assert pct and pct[-1] == 100, drawn[-2000:]
    assert pct == sorted(pct)
    assert screen_of(raw)[-1].startswith(f"wrote {tmp_path / 'b.exr'}")


def run_to_file(args: list[str], path: Path, monkeypatch) -> tuple[int, list[str]]:
    """Run ``shprobe ARGS`` in this process with stdout and stderr sent to one file; its
    return code and the file's lines. Every stage gets its log line (no second's wait)."""
    from shprobe.cli import progress as terminal
    from shprobe.cli.main import main

    monkeypatch.setattr(terminal, "LOG_AFTER", 0.0)
    with open(path, "w", encoding="utf-8") as f:
        monkeypatch.setattr(sys, "stdout", f)
        monkeypatch.setattr(sys, "stderr", f)
        rc = main(args)
        f.flush()
    monkeypatch.undo()
    return rc, path.read_text(encoding="utf-8").split("\n")


@pytest.mark.parametrize("name", list(COMMANDS))
def test_to_a_file(name, data, tmp_path, monkeypatch):
    (tmp_path / "out").mkdir()
    args, names = _args(name, data, tmp_path / "out")
    rc, lines = run_to_file(args, tmp_path / "log.txt", monkeypatch)
    text = "\n".join(lines)
    assert rc == 0, text
    assert lines[-1] == "", "the log ends with a newline"
    lines = lines[:-1]
    assert all(ln.strip() for ln in lines), f"a blank line in the log:\n{text}"
    assert not CONTROL.search(text), f"control codes in the log: {text!r}"
    assert lines[-1].startswith(f"wrote {names}"), text
    for ln in lines[:-1]:
        m = re.match(r"(\d+)/(\d+): .+ …$", ln)
        if m:
            assert 1 <= int(m[1]) <= int(m[2])


def test_quiet_prints_nothing_and_verbose_adds_detail(data, tmp_path, monkeypatch):
    rc, lines = run_to_file(["-q", "basis-images", "--sphere", "--size", "16x16", "-o",
                             str(tmp_path / "q")], tmp_path / "q.txt", monkeypatch)
    assert rc == 0 and lines == [""]
    rc, lines = run_to_file(["-v", "basis-images", "--sphere", "--size", "16x16", "-o",
                             str(tmp_path / "v")], tmp_path / "v.txt", monkeypatch)
    assert rc == 0 and lines[-2].startswith(f"wrote 19 files in {tmp_path / 'v'}")
    listed = [ln.strip() for ln in lines if ln.startswith("  ")]
    assert sorted(listed) == sorted(str(p) for p in (tmp_path / "v").iterdir())


def test_tables_only_when_they_are_the_product(data, tmp_path, monkeypatch):
    """`hbasis study -o` keeps its tables in its files; --table prints them too; `demo`
    prints its tables only with --table; `error` (its product is a table) prints it."""
    rc, lines = run_to_file(["hbasis", "study", "--signals", "20", "-o", str(tmp_path / "s")],
                            tmp_path / "s.txt", monkeypatch)
    assert rc == 0 and not any("|" in ln for ln in lines)
    rc, lines = run_to_file(["hbasis", "study", "--signals", "20", "--table", "--force", "-o",
                             str(tmp_path / "s")], tmp_path / "t.txt", monkeypatch)
    assert rc == 0 and any("| H6 |" in ln for ln in lines)
    rc, lines = run_to_file(["demo", "--table", "--size", "32x16", "--out",
                             str(tmp_path / "d")], tmp_path / "d.txt", monkeypatch)
    assert rc == 0 and any("L2-2" in ln for ln in lines) and any("sMAPE" in ln for ln in lines)
    rc, lines = run_to_file(["error", str(data / "probe.hdr"), "--normals", "4", "-F", "json"],
                            tmp_path / "e.txt", monkeypatch)
    assert rc == 0 and '"rows"' in "\n".join(lines)


def test_a_long_job_says_its_estimate_first(data, tmp_path, monkeypatch):
    """A job whose cost model (the one its memory check uses) says over 30 s prints the
    estimate before it starts; a short one does not."""
    from shprobe.lighting import reference
    from shprobe.limits import cores, format_bytes, format_seconds
    from shprobe.probes.env import load_env

    args = ["irradiance", str(data / "probe.hdr"), "--method", "brute", "--size", "16x8",
            "-o", str(tmp_path / "a.exr")]
    rc, lines = run_to_file(args, tmp_path / "short.txt", monkeypatch)
    assert rc == 0 and not any("on this machine" in ln for ln in lines)
    monkeypatch.setattr(reference, "PAIRS_PER_CORE_SECOND", 1e3)  # a slow machine
    cost = reference.reference_cost(load_env(data / "probe.hdr"), 16 * 8)
    assert cost.seconds > 30
    args[-1] = str(tmp_path / "b.exr")
    from shprobe.cli import progress as terminal
    from shprobe.cli.main import main

    monkeypatch.setattr(terminal, "LOG_AFTER", 0.0)
    path = tmp_path / "long.txt"
    with open(path, "w", encoding="utf-8") as f:
        monkeypatch.setattr(sys, "stderr", f)
        rc = main(args)
        monkeypatch.undo()
    assert rc == 0
    lines = path.read_text(encoding="utf-8").splitlines()
    said = (f"the brute-force irradiance map 16x8: about {format_seconds(cost.seconds)} and "
            f"{format_bytes(cost.nbytes)} on this machine ({cores()} cores)")
    assert said in lines and lines[-1].startswith("wrote ")
    assert lines[lines.index(said) + 1] == "exact irradiance at 128 normals (brute force) …"


def test_an_estimate_over_the_memory_limit_is_a_one_line_refusal(tmp_path, monkeypatch):
    rc, lines = run_to_file(["--max-memory", "1G", "hbasis", "study", "--signals", "200000",
                             "-o", str(tmp_path / "s")], tmp_path / "log.txt", monkeypatch)
    assert rc == 1 and len(lines) == 2 and lines[1] == ""
    assert lines[0].startswith("shprobe: error: the study of 200,000 signals would need about")
    assert not (tmp_path / "s").exists()
