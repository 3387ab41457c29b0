"""rayscan.write when the system refuses: a failed system call raises the OSError subclass for its
errno with the user's path as filename (as rayscan.read and Python's open() do), and a signal that
ends the process mid-write leaves no temporary file. Oracles: the errno the kernel gives (a missing
folder, a file size limit: RLIMIT_FSIZE gives EFBIG, as a full disk gives ENOSPC, on the same
write), the folder's entries, the child's exit status and its signal masks in /proc/PID/status."""

import errno
import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import rayscan

FORMATS = ["out.las", "out.laz", "out.ply", "out.pcd", "out.xyz"]


def test_missing_folder_is_file_not_found_named_by_the_path(tmp_path):
    pc = np.zeros((3, 3))
    for name in FORMATS:
        path = tmp_path / "missing" / name
        with pytest.raises(FileNotFoundError) as e:
            rayscan.write(path, pc)
        assert e.value.errno == errno.ENOENT and e.value.filename == str(path)
        assert e.value.strerror == os.strerror(errno.ENOENT)
        # The library's own line is kept as a note.
        assert any("does not exist" in n for n in getattr(e.value, "__notes__", [])), e.value.__notes__
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError) as e:
        rayscan.write(tmp_path / "file" / "out.las", pc)
    assert e.value.errno == errno.ENOTDIR and e.value.filename == str(tmp_path / "file" / "out.las")
    (tmp_path / "dir.las").mkdir()
    with pytest.raises(IsADirectoryError) as e:
        rayscan.write(tmp_path / "dir.las", pc)
    assert e.value.errno == errno.EISDIR
    # A refusal by rule, not by a failed call: a plain OSError with the library's message.
    os.mkfifo(tmp_path / "fifo.las")
    with pytest.raises(OSError, match="fifo.las: is a FIFO") as e:
        rayscan.write(tmp_path / "fifo.las", pc)
    assert type(e.value) is OSError and e.value.errno is None


@pytest.mark.parametrize("name", FORMATS)
def test_failed_write_carries_its_errno_and_leaves_no_file(tmp_path, name):
    # RLIMIT_FSIZE makes the write past its byte fail with EFBIG (SIGXFSZ ignored), as a full disk
    # fails it with ENOSPC: the errno of the failed write, not a message-only OSError.
    pc = np.random.default_rng(1).random((200_000, 3))
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, hard))
    try:
        with pytest.raises(OSError) as e:
            rayscan.write(tmp_path / name, pc)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old_handler)
    assert e.value.errno == errno.EFBIG and e.value.filename == str(tmp_path / name)
    assert e.value.strerror == os.strerror(errno.EFBIG)
    assert os.listdir(tmp_path) == []  # neither the output nor a temporary


def signal_masks(pid="self"):
    """The caught and ignored signal masks (SigCgt, SigIgn) of /proc/PID/status."""
    with open(f"/proc/{pid}/status") as f:
        fields = dict(line.split(":\t", 1) for line in f if line.startswith(("SigCgt", "SigIgn")))
    return int(fields["SigCgt"], 16), int(fields["SigIgn"], 16)


def caught(mask, sig):
    return bool(mask >> (sig - 1) & 1)


def test_write_leaves_the_signal_actions_as_it_found_them(tmp_path):
    before = signal_masks()
    rayscan.write(tmp_path / "out.ply", np.zeros((10, 3)))
    assert signal_masks() == before


# Writes a large cloud over and over until a signal ends it; argv: output path, "default" (SIGTERM's
# action left as Python starts) or "host" (the host handles SIGTERM: it exits with 3).
CHILD = """
import signal, sys
import numpy as np
import rayscan
if sys.argv[2] == "host":
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(3))
xyz = np.random.default_rng(0).random((2_000_000, 3))
while True:
    rayscan.write(sys.argv[1], xyz)
"""


def stopped(pid):
    with open(f"/proc/{pid}/stat") as f:
        return f.read().rsplit(")", 1)[1].split()[0] in ("T", "t")


def stop_mid_write(proc, temp):
    """Stops the child (SIGSTOP) at a moment its temporary file exists, so that it is mid-write."""
    guard = time.monotonic() + 120  # against a hang only: each write takes well under a second
    while time.monotonic() < guard:
        assert proc.poll() is None, proc.communicate()[1]
        if temp.exists():
            os.kill(proc.pid, signal.SIGSTOP)
            while not stopped(proc.pid):
                time.sleep(0.001)
            if temp.exists():
                return
            os.kill(proc.pid, signal.SIGCONT)
        time.sleep(0.001)
    pytest.fail("the child's temporary file never appeared")


@pytest.mark.parametrize("host", ["default", "host"])
def test_sigterm_mid_write_leaves_no_temporary(tmp_path, host):
    out = tmp_path / "big.ply"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(out), host], stderr=subprocess.PIPE, text=True)
    temp = tmp_path / f".big.ply.tmp.{proc.pid}"
    try:
        stop_mid_write(proc, temp)
        # Mid-write, SIGTERM is caught either way: by rayscan's handler while its action is the
        # default one, else by the host's (Python's) handler.
        assert caught(signal_masks(proc.pid)[0], signal.SIGTERM)
        os.kill(proc.pid, signal.SIGTERM)
        os.kill(proc.pid, signal.SIGCONT)
        _, err = proc.communicate()
    finally:
        if proc.poll() is None:
            proc.kill()
            os.kill(proc.pid, signal.SIGCONT)
            proc.wait()
    if host == "default":
        # The temporary removed, then the process ended by SIGTERM itself, as without rayscan.
        assert proc.returncode == -signal.SIGTERM, err
    else:
        # The host's handler kept: Python runs it once the write has returned, and it exits 3.
        assert proc.returncode == 3, err
    assert not [n for n in os.listdir(tmp_path) if ".tmp." in n], os.listdir(tmp_path)
