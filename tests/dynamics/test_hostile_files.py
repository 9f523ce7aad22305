"""Scene and URDF files are data of bounded size: every hostile or broken file gets one clear
error (exit 2) naming the file and the problem, within seconds and bounded memory, and leaves
nothing behind (tests/adversarial.py states the contract). The references are the file system's
own facts (a FIFO, a device, a size, the byte that is not UTF-8) and the scene format."""
from __future__ import annotations

import os
import shutil
import socket
import tracemalloc
from pathlib import Path

import pytest
from adversarial import CAR, ROOT, answer

EXAMPLES = ROOT / "examples"
CAR_TEXT = Path(CAR).read_text()
RACER_SCENE = (EXAMPLES / "roller_racer_urdf.toml").read_text()
RACER_URDF = (EXAMPLES / "roller_racer.urdf").read_text()


# ----------------------------------------------------------------------------- scene files
def _write(folder: Path, name: str, data) -> Path:
    path = folder / name
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    return path


def _fifo(folder):
    path = folder / "pipe.toml"
    os.mkfifo(path)
    return path


def _socket(folder):
    path = folder / "s.toml"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(path))
    sock.close()
    return path


def _sparse(folder, size=200 * 2**20):
    path = folder / "huge.toml"
    with open(path, "wb") as fh:
        fh.write(CAR_TEXT.encode())
        fh.truncate(size)                           # 200 MB that occupy no disk
    return path


def _link_to(target):
    def make(folder):
        path = folder / "link.toml"
        path.symlink_to(target)
        return path
    return make


def _loop(folder):
    (folder / "a.toml").symlink_to(folder / "b.toml")
    (folder / "b.toml").symlink_to(folder / "a.toml")
    return folder / "a.toml"


def _nested_arrays(folder, depth=100_000):
    return _write(folder, "deep.toml", "[system]\ncoordinates = " + "[" * depth + "]" * depth + "\n")


def _many_keys(folder, count=20_000):
    return _write(folder, "keys.toml",
                  CAR_TEXT + "\n[extra]\n" + "".join(f"k{i} = {i}\n" for i in range(count)))


SCENE_FILES = [
    # (id, make(folder) -> path, expected statuses, what the message must say)
    ("latin-1", lambda f: _write(f, "l.toml", CAR_TEXT.replace("# A car", "# A café car").encode("latin-1")),
     2, r"not UTF-8 text: byte 0xe9 at position \d+ \(line 1, column \d+\).*Latin-1"),
    ("utf-16-le", lambda f: _write(f, "u.toml", CAR_TEXT.encode("utf-16")), 2, r"UTF-16 text"),
    ("utf-16-be", lambda f: _write(f, "u.toml", b"\xfe\xff" + CAR_TEXT.encode("utf-16-be")), 2,
     r"UTF-16 text"),
    ("utf-8 with a byte-order mark", lambda f: _write(f, "bom.toml", b"\xef\xbb\xbf" + CAR_TEXT.encode()), 0,
     r"car"),
    ("binary garbage", lambda f: _write(f, "g.toml", bytes(range(128, 256)) * 64), 2, r"not UTF-8 text"),
    ("NUL bytes", lambda f: _write(f, "n.toml", CAR_TEXT.replace("[units]", "[units]\0")), 2,
     r"TOML syntax error"),
    ("empty file", lambda f: _write(f, "e.toml", b""), 2, r"missing \[system\] table"),
    ("a directory", lambda f: (f / "d.toml").mkdir() or f / "d.toml", 2,
     r"is a directory, not a regular file"),
    ("a FIFO", _fifo, 2, r"is a FIFO \(named pipe\), not a regular file"),
    ("a socket", _socket, 2, r"is a socket, not a regular file"),
    ("/dev/zero", lambda f: Path("/dev/zero"), 2, r"/dev/zero is a character device"),
    ("/dev/null", lambda f: Path("/dev/null"), 2, r"/dev/null is a character device"),
    ("/dev/urandom", lambda f: Path("/dev/urandom"), 2, r"character device"),
    ("/proc/self/mem", lambda f: Path("/proc/self/mem"), 2, r"/proc/self/mem cannot be read"),
    ("a link to /dev/zero", _link_to("/dev/zero"), 2, r"character device"),
    ("a link loop", _loop, 2, r"cannot be opened"),
    ("a missing file", lambda f: f / "nothere.toml", 2, r"does not exist"),
    ("a name longer than the system allows", lambda f: f / ("x" * 5000 + ".toml"), 2,
     r"too long|does not exist"),
    ("200 MB (sparse)", _sparse, 2, r"larger than 4 MiB"),
    ("100 000 nested arrays", _nested_arrays, 2, r"TOML syntax error|nested"),
    ("20 000 keys in an unknown table", _many_keys, 2, r"unknown top-level table"),
    ("a TOML date "
     "as a parameter", lambda f: _write(f, "d.toml", CAR_TEXT.replace("m = 1.0 ", "m = 1979-05-27 ")), 2,
     r"parameter 'm'"),
    ("a string that is code", lambda f: _write(f, "c.toml",
                                               CAR_TEXT.replace('m = 1.0 ', 'm = "__import__(\'os\')" ')), 2,
     r"parameter 'm'"),
    ("unterminated string", lambda f: _write(f, "s.toml", '[system]\nname = "car\n'), 2,
     r"TOML syntax error"),
    ("a lone surrogate", lambda f: _write(f, "s.toml", b'[system]\nname = "\xed\xa0\x80"\n'), 2,
     r"not UTF-8 text"),
]


@pytest.mark.skipif(not Path("/proc/self/mem").exists(), reason="Linux /proc and devices")
@pytest.mark.parametrize("make, statuses, said", [pytest.param(*c[1:], id=c[0]) for c in SCENE_FILES])
def test_a_hostile_scene_file_gets_one_clear_answer(make, statuses, said, sandbox):
    """``nhgait derive FILE``: exit 2 naming the file and what is wrong with it (0 for a UTF-8
    byte-order mark, which is accepted); at most 4 MiB + 1 byte is read whatever the file claims
    (the 200 MB file, /dev/zero: traced allocations stay under 64 MB)."""
    path = make(sandbox.root)
    tracemalloc.start()
    try:
        got = answer(["derive", path, "--no-cache"] if statuses == 0 else ["derive", path])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    got.check(statuses, said, sandbox)
    assert peak < 64 * 2**20, peak


def test_read_text_file_names_the_first_byte_that_is_not_utf8(tmp_path):
    """The byte, its position, line and column, counted from the file itself."""
    from nhgait.dynamics.derivation.input.textfiles import read_text_file
    from nhgait.dynamics.errors import ModelError
    data = b"[system]\nname = 'ok'\n# caf\xe9\n"
    (tmp_path / "s.toml").write_bytes(data)
    with pytest.raises(ModelError) as err:
        read_text_file(tmp_path / "s.toml", "scene file")
    position = data.index(b"\xe9")
    assert f"byte 0xe9 at position {position} (line 3, column 6)" in str(err.value)


def test_a_directory_is_one_problem_not_an_error_inside_an_error(tmp_path):
    """A directory where a file is read: one sentence, the title said once (it was the whole
    first error quoted inside a second: "cannot be opened (cannot read …: 1 problem(s) …)")."""
    from nhgait.dynamics.derivation.input.textfiles import read_text_file
    from nhgait.dynamics.errors import ModelError
    with pytest.raises(ModelError) as err:
        read_text_file(tmp_path, "solution file", title="cannot read the solution")
    assert err.value.problems == (f"solution file {tmp_path} is a directory, not a regular file",)
    assert str(err.value).count("problem(s)") == 1


# ----------------------------------------------------------------------------- URDFs
def _urdf_scene(folder: Path, urdf_line: str, urdf_text: str | None = RACER_URDF, name="robot.urdf") -> Path:
    if urdf_text is not None:
        (folder / name).write_text(urdf_text)
    scene = RACER_SCENE.replace('urdf = "roller_racer.urdf"', urdf_line)
    return _write(folder, "scene.toml", scene)


def _chain(links: int, joint_type: str = "fixed") -> str:
    """A URDF of ``links`` + 1 links in one chain under a planar base."""
    inertial = ('<inertial><mass value="0.01"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" '
                'izz="1e-5"/></inertial>')
    body = "".join(f'<link name="l{i}">{inertial}</link>' for i in range(links + 1))
    axis = '<axis xyz="0 0 1"/>' if joint_type != "fixed" else ""
    joints = "".join(f'<joint name="j{i}" type="{joint_type}"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0.001 0 0"/>{axis}</joint>' for i in range(links))
    return f'<?xml version="1.0"?><robot name="chain">{body}{joints}</robot>'


def _chain_scene(links, joint_type="fixed"):
    def make(folder):
        (folder / "chain.urdf").write_text(_chain(links, joint_type))
        return _write(folder, "chain.toml", '[system]\nurdf = "chain.urdf"\nbase = "planar"\n')
    return make


def _outside_link(folder):
    (folder / "inside.urdf").symlink_to("/etc/passwd")
    return _urdf_scene(folder, 'urdf = "inside.urdf"', None)


def _billion_laughs(folder):
    entities = '<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">' + "".join(
        f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(8)) + "]>"
    return _urdf_scene(folder, 'urdf = "robot.urdf"', entities + '<robot name="r"><link name="&i;"/></robot>')


def _deep_xml(folder, depth=50_000):
    return _urdf_scene(folder, 'urdf = "robot.urdf"',
                       '<robot name="r">' + "<a>" * depth + "</a>" * depth + "</robot>")


URDF_FILES = [
    ("a chain of 1000 fixed links", _chain_scene(1000), 0, r"chain"),
    ("a chain of 300 locked revolute joints", _chain_scene(300, "revolute"), 0, r"chain"),
    ("/etc/shadow", lambda f: _urdf_scene(f, 'urdf = "/etc/shadow"', None), 2,
     r"'/etc/shadow' is outside the scene's folder"),
    ("../../../etc/passwd", lambda f: _urdf_scene(f, 'urdf = "../../../../../../../etc/passwd"', None), 2,
     r"is outside the scene's folder"),
    ("a link inside the folder to /etc/passwd", _outside_link, 2,
     r"'inside.urdf' is outside the scene's folder"),
    ("example-robot-data:../../..",
     lambda f: _urdf_scene(f, 'urdf = "example-robot-data:../../../../../../etc/passwd"', None), 2,
     r"outside|example-robot-data package"),
    ("a number", lambda f: _urdf_scene(f, "urdf = 42", None), 2, r"must be a file name"),
    ("a missing URDF", lambda f: _urdf_scene(f, 'urdf = "nothere.urdf"', None), 2, r"does not exist"),
    ("a directory", lambda f: (f / "d.urdf").mkdir() or _urdf_scene(f, 'urdf = "d.urdf"', None), 2,
     r"is a directory, not a regular file"),
    ("a FIFO", lambda f: os.mkfifo(f / "p.urdf") or _urdf_scene(f, 'urdf = "p.urdf"', None), 2, r"is a FIFO"),
    ("latin-1", lambda f: _write(f, "robot.urdf", RACER_URDF.replace("racer", "racér").encode("latin-1"))
     and _urdf_scene(f, 'urdf = "robot.urdf"', None), 2, r"URDF .* is not UTF-8 text: byte 0xe9"),
    ("utf-16", lambda f: _write(f, "robot.urdf", RACER_URDF.encode("utf-16"))
     and _urdf_scene(f, 'urdf = "robot.urdf"', None), 2, r"UTF-16"),
    ("5 MB", lambda f: _urdf_scene(f, 'urdf = "robot.urdf"',
                                   RACER_URDF.replace("</robot>", "<!--" + "x" * (5 << 20) + "--></robot>")),
     2, r"larger than 4 MiB"),
    ("a mass of 1e308", lambda f: _urdf_scene(f, 'urdf = "robot.urdf"',
                                              RACER_URDF.replace('<mass value="1.5"/>',
                                                                 '<mass value="1e308"/>')),
     2, r"mass: value = '1e308'|1e\+308 exceeds 1e\+15"),
    ("an inertia of inf", lambda f: _urdf_scene(f, 'urdf = "robot.urdf"',
                                                RACER_URDF.replace('izz="0.04"', 'izz="inf"')),
     2, r"not a finite number|not 6 finite numbers"),
    ("an origin of 1e300", lambda f: _urdf_scene(f, 'urdf = "robot.urdf"',
                                                 RACER_URDF.replace('xyz="-0.3 0 0"', 'xyz="-1e300 0 0"')),
     2, r"exceeds 1e\+15"),
    ("billion laughs", _billion_laughs, 2, r"document type declaration"),
    ("50 000 nested elements", _deep_xml, 2, r"robot|link"),
    ("not XML", lambda f: _urdf_scene(f, 'urdf = "robot.urdf"', "root:x:0:0:root:/root:/bin/bash\n"), 2,
     r"malformed XML"),
]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX files")
@pytest.mark.parametrize("make, statuses, said", [pytest.param(*c[1:], id=c[0]) for c in URDF_FILES])
def test_a_hostile_urdf_gets_one_clear_answer(make, statuses, said, sandbox):
    """A scene naming a URDF: files outside the scene's folder tree are refused before they are
    opened (the message does not say whether they exist); the URDF is read as bounded UTF-8
    text; its tree is walked without recursion (1000 fixed links merge into one body)."""
    got = answer(["derive", make(sandbox.root), "--no-cache"]).check(statuses, said, sandbox)
    if "outside" in (said or ""):
        assert "malformed" not in got.err
        assert "exist" not in got.err


def test_a_folder_the_user_allows_may_hold_the_urdf(sandbox, monkeypatch):
    """``$NHGAIT_URDF_PATH`` is the user's explicit permission for a folder outside the scene's."""
    elsewhere = sandbox.root / "robots"
    elsewhere.mkdir()
    shutil.copy(EXAMPLES / "roller_racer.urdf", elsewhere / "racer.urdf")
    scene_dir = sandbox.root / "scenes"
    scene_dir.mkdir()
    scene = _urdf_scene(scene_dir, f'urdf = "{elsewhere / "racer.urdf"}"', None)
    answer(["derive", scene]).check(2, r"outside the scene's folder.*NHGAIT_URDF_PATH", sandbox)
    monkeypatch.setenv("NHGAIT_URDF_PATH", str(elsewhere))
    got = answer(["derive", scene]).check(0, None, sandbox)
    assert "theta" in got.out  # the roller racer's q = (x, y, theta, phi)
    assert "phi" in got.out


def test_a_chain_of_fixed_links_merges_into_one_body_with_their_mass():
    """1000 fixed links of 0.01 kg under the root: one body of 10.01 kg (the sum), built
    without recursion; its centre of mass at the mean of the links' positions (0.5 m)."""
    from nhgait.dynamics.derivation.urdf.reader import read_urdf
    from nhgait.dynamics.derivation.urdf.tree import build_bodies, tree_problems
    robot = read_urdf(_chain(1000), "chain.urdf")
    problems, root = tree_problems(robot)
    assert problems == []
    assert root == "l0"
    (body,) = build_bodies(robot, root, {}, {})
    assert body.mass == pytest.approx(1001 * 0.01, rel=1e-12)
    assert body.com[0] == pytest.approx(0.001 * 1000 / 2, rel=1e-9)    # mean of 0, 0.001, …, 1.0 m
