"""The compiled-kernel cache cannot lie: checked before import, repaired, private."""

from __future__ import annotations

import os
import shutil
import sys

import numpy as np
import pytest

from balancer_id.model import parse_model
from balancer_id.simulation import Thrust, simulate
from balancer_id.simulation import kernel as K
from balancer_id.simulation import kernel_cache as KCache
from balancer_id.simulation import kernel_compile as KC

T = np.arange(0.0, 2.0, 0.005)
PARAMS = {"m_a": 15.1, "T_a": 0.33}


@pytest.fixture(scope="module", autouse=True)
def _own_kernels():
    """The tests here are about a model's own kernel file (test_shared_kernel.py: the
    shared one)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BALANCER_ID_KERNELS", "own")
        mp.setattr(KCache, "_CHOSEN", {})
        yield


@pytest.fixture(scope="module", autouse=True)
def _process_kernels_kept():
    """The tests here forget the process's kernel modules (what a new process sees); the
    kernels memoized before them (``K._KERNELS``, restored after each test) get their
    modules back afterwards, as the later tests of the same worker process expect (numba
    imports a kernel's module by name when it loads another signature from disk)."""
    kept = {n: m for n, m in sys.modules.items() if n.startswith("bid_kernel_")}
    yield
    for name in [n for n in sys.modules if n.startswith("bid_kernel_")]:
        del sys.modules[name]
    sys.modules.update(kept)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """A cache holding the compiled 'base' kernel (plain and sensitivities), made once."""
    root = tmp_path_factory.mktemp("compiled")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BALANCER_ID_CACHE", str(root))
        mp.setattr(K, "_KERNELS", {})
        _forget()
        accel = _accel()
        _forget()
    return root, accel


@pytest.fixture
def warm_cache(compiled, tmp_path, monkeypatch):
    """A copy of the compiled cache (what a second run finds); the expected output."""
    root, accel = compiled
    shutil.copytree(root, tmp_path / "cache", copy_function=shutil.copy2)
    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(K, "_KERNELS", {})
    monkeypatch.setattr(K, "_warm", lambda *a: None)  # recompile the plain kernel only
    _forget()
    yield tmp_path / "cache" / "kernels", accel
    _forget()


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty kernel cache and no kernel memoized in this process."""
    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(K, "_KERNELS", {})
    _forget()
    yield tmp_path / "cache" / "kernels"
    _forget()


def _accel() -> np.ndarray:
    return simulate(parse_model("base"), PARAMS, T, Thrust.step(0.5, 4.9)).accel


def _forget() -> None:
    """What a new process would see: nothing memoized, nothing imported."""
    K._KERNELS.clear()
    KCache._CHOSEN.clear()
    for name in [n for n in sys.modules if n.startswith("bid_kernel_")]:
        del sys.modules[name]


def test_a_new_cache_folder_is_private_and_a_first_compile_is_announced(
    fresh_cache, capfd, monkeypatch
):
    found_cached = []  # whether each kernel was in the disk cache when loaded here
    load = K._compile_now
    monkeypatch.setattr(
        K,
        "_compile_now",
        lambda model, kernel, quiet=False: (
            found_cached.append(K._is_cached_path(kernel.path)) or load(model, kernel, quiet)
        ),
    )
    monkeypatch.setattr(KC, "COMPILE_JOBS", 2)
    models = [parse_model("base"), parse_model("viscous")]
    KC.compile_models(models)  # two missing kernels: one compiled here, one by a helper process
    err = capfd.readouterr().err
    assert "compiling the simulation kernel of 'base' (1/2; once)" in err
    assert "compiling the simulation kernel of 'viscous' (2/2; once)" in err
    assert found_cached == [False, True]  # 'viscous' was in the cache when loaded here
    KC.compile_models(models)  # already there: nothing to say
    assert capfd.readouterr().err == ""
    _forget()
    want = _accel()
    assert fresh_cache.is_dir() and (fresh_cache.stat().st_mode & 0o777) == 0o700
    sources = list(fresh_cache.glob("bid_kernel_*.py"))
    assert len(sources) == 2 and all((src.stat().st_mode & 0o077) == 0 for src in sources)
    _forget()
    assert np.allclose(
        _accel(), want, rtol=1e-12, atol=1e-15
    )  # loaded from the cache: nothing announced
    err = capfd.readouterr().err
    assert "compiling" not in err, err


def test_a_tampered_kernel_source_is_never_imported(warm_cache, capfd):
    folder, want = warm_cache
    (src,) = folder.glob("bid_kernel_*.py")
    marker = folder.parent / "pwned"
    src.write_text(f"open({str(marker)!r}, 'w').close()\n" + src.read_text())
    _forget()
    capfd.readouterr()
    assert np.allclose(_accel(), want, rtol=1e-12, atol=1e-15)
    assert not marker.exists()
    assert "did not match its model; rewriting it" in capfd.readouterr().err
    assert "open(" not in src.read_text()


def test_a_corrupted_kernel_file_is_regenerated(warm_cache, capfd):
    folder, want = warm_cache
    (src,) = folder.glob("bid_kernel_*.py")
    src.write_bytes(b"\xff\xfe garbage \x00")
    _forget()
    assert np.allclose(_accel(), want, rtol=1e-12, atol=1e-15)
    assert "rewriting it" in capfd.readouterr().err


def test_a_damaged_numba_cache_is_recompiled_not_blamed_on_the_effects(warm_cache, capfd):
    folder, want = warm_cache
    damaged = list((folder / "__pycache__").glob("bid_kernel_*"))
    assert any(p.suffix == ".nbc" for p in damaged)
    for p in damaged:
        p.write_bytes(b"\x80\x04 not a pickle")
    _forget()
    assert np.allclose(_accel(), want, rtol=1e-12, atol=1e-15)
    _forget()
    assert np.allclose(
        _accel(), want, rtol=1e-12, atol=1e-15
    )  # and the repaired cache serves the next run


def test_a_cache_writable_by_others_is_refused(tmp_path, monkeypatch, capfd):
    shared = tmp_path / "shared"
    (shared / "kernels").mkdir(parents=True)
    os.chmod(shared / "kernels", 0o777)
    monkeypatch.setenv("BALANCER_ID_CACHE", str(shared))
    monkeypatch.setattr(K, "_KERNELS", {})
    monkeypatch.setattr(K, "_REFUSED", set())
    _forget()
    accel = _accel()
    assert np.all(np.isfinite(accel)) and accel.max() > 0
    assert not list((shared / "kernels").iterdir())  # nothing written, nothing imported
    err = capfd.readouterr().err
    assert "kernel cache not used" in err and "writable by others" in err
    assert err.count("\n") == 1



def test_a_model_whose_hook_raises_is_compiled_once_and_its_error_raised_again(monkeypatch):
    # a user's force that raises: its kernel was compiled (and "regenerated" as if the
    # cache were damaged) at every refit of a diagnosis, 12 compiles for two such effects
    from balancer_id import Effect, Param
    from balancer_id.errors import EffectError
    from balancer_id.model import Registry

    class Raises(Effect):
        """A force that raises."""

        name = "raises_once"
        summary = "raises"
        parameters = (Param("k_q", 1.0, 0.0, 2.0, "N", "nothing"),)

        @staticmethod
        def force(f, v, z, h, k_q):
            raise RuntimeError("boom")

    registry = Registry()
    registry.add(Raises)
    model = parse_model("variable_viscosity+raises_once", registry)
    compiled: list[str] = []
    real = K._compile_now

    def counted(m, *a, **k):
        compiled.append(m.spec)
        return real(m, *a, **k)

    monkeypatch.setattr(K, "_compile_now", counted)
    with pytest.raises(EffectError, match="raises_once") as first:
        K.get_kernel(model, quiet=True)
    n = len(compiled)
    assert 1 <= n <= 2  # a fresh compile, or a cached one regenerated once
    with pytest.raises(EffectError) as again:
        K.get_kernel(model, quiet=True)
    assert len(compiled) == n and str(again.value) == str(first.value)


def test_a_kernel_being_compiled_is_waited_for_not_compiled_twice(tmp_path, monkeypatch):
    """Two builders of one uncached kernel (a batch's workers on a fresh machine) take
    turns: the second enters only when the first has left, then finds the cache filled."""
    import threading
    import time

    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path))
    model = parse_model("viscous")
    entered = threading.Event()

    def second() -> None:
        with KCache.compile_lock(model):
            entered.set()

    with KCache.compile_lock(model):
        worker = threading.Thread(target=second)
        worker.start()
        time.sleep(0.3)
        assert not entered.is_set()  # held off while the first builds
    assert entered.wait(5.0)
    worker.join()
    assert list((tmp_path / "kernels").glob("*.lock"))  # the lock file, beside the kernel
