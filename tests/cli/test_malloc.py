"""The stability command's malloc settings (:func:`critfric.guards.keep_freed_memory`): set
by the command's own process only, on glibc, unless the user set glibc's malloc."""

from __future__ import annotations

import os
import platform
import signal
import subprocess
import sys

import pytest

from critfric import cli, guards

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

GLIBC = platform.libc_ver()[0] == "glibc"
PROBE = ("from critfric.guards import keep_freed_memory as k, freed_memory_kept as f; "
         "before = f(); print(k(), before, f())")


def _probe(**env) -> str:
    clean = {k: v for k, v in os.environ.items()
             if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run([sys.executable, "-c", PROBE], env=clean | env, capture_output=True,
                         text=True, check=True)
    return out.stdout.strip()


@pytest.mark.skipif(not GLIBC, reason="glibc's mallopt")
def test_set_on_glibc_unless_the_user_set_malloc():
    assert _probe() == "True False True"
    assert _probe(MALLOC_ARENA_MAX="2") == "False False False"
    assert _probe(GLIBC_TUNABLES="glibc.malloc.mmap_max=0") == "False False False"
    assert _probe(GLIBC_TUNABLES="glibc.rtld.optional_static_tls=2048") == "True False True"


@pytest.fixture
def signals():
    """SIGINT's and SIGTERM's handlers put back (main() ignores both once a command ends)."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


@pytest.mark.parametrize("argv, asked", [(["-v", "stability", "--help"], True),
                                         (["stability", "--help"], True),
                                         (["solve", "--help"], False), (["--help"], False)])
def test_only_the_stability_command_asks(monkeypatch, signals, argv, asked):
    calls = []
    monkeypatch.setattr(guards, "keep_freed_memory", lambda: calls.append(1))
    monkeypatch.setattr(sys, "argv", ["critfric", *argv])
    with pytest.raises(SystemExit) as ended:
        cli.main()
    assert ended.value.code == 0
    assert calls == ([1] if asked else [])
