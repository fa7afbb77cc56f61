"""The compiled-code cache on disk: where it is, what it holds, and emptying it (`stickslip
cache info`, `stickslip cache clear`). No JAX import: the command stays quick.

The cache directory (`stickslip._jax` sets JAX's persistent cache to it) holds

- `stickslip-exported/`: the simulator's traces (portable, for every CPU);
- `stickslip-executable/<CPU kind>/`: compiled executables, one folder per CPU kind
  (`stickslip._cpu.KIND`), since XLA compiles for the CPU it runs on;
- `stickslip-queue/<CPU kind>/`: the background compiler's queue (`stickslip._background`);
- JAX's own entries (`*-cache` files: the chain's and the smaller programs).
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import stat

OFF = ("", "off", "0", "none", "false")
OURS = ("stickslip-exported", "stickslip-executable", "stickslip-queue")
SHIPPED = pathlib.Path(__file__).parent / "_data" / "traces"


def own_directory() -> pathlib.Path | None:
    """The directory stickslip gives JAX's persistent cache unless one is configured for
    JAX itself: `$STICKSLIP_CACHE_DIR`, default `$XDG_CACHE_HOME/stickslip/jax` (or
    `~/.cache/stickslip/jax`); `None` where `STICKSLIP_CACHE_DIR` turns it off."""
    where = os.environ.get("STICKSLIP_CACHE_DIR")
    if where is not None:
        return None if where.strip().lower() in OFF else pathlib.Path(where).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or pathlib.Path.home() / ".cache"
    return pathlib.Path(base) / "stickslip" / "jax"


def trusted(st: os.stat_result) -> bool:
    """Whether a file or folder with this status may hold compiled code this process loads
    (an executable is code: loading one runs it): it belongs to this user, or to root, and
    neither its group nor others may write it."""
    if not hasattr(os, "getuid"):  # (no owners to check: Windows)
        return True
    return st.st_uid in (os.getuid(), 0) and not st.st_mode & 0o022


def prepare(where: pathlib.Path, tighten: bool = False) -> str | None:
    """Make the cache directory `where` (readable and writable by this user only) or check
    the one there; `None` if it may be used, else why not: it belongs to another user, or
    its group or others may write it (a folder shared by several users would run one
    user's code in another's process). With `tighten` (stickslip's own default folder,
    which no one else has reason to write), such a folder of this user's is closed to the
    others instead; a folder named by the user is never changed."""
    try:
        where.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = where.stat()
    except OSError as err:  # a read-only home: run without the cache
        return f"it cannot be made ({err.strerror})"
    if not where.is_dir():
        return "it is not a folder"
    if trusted(st):
        return None
    ours = hasattr(os, "getuid") and st.st_uid == os.getuid()
    if ours and tighten and not st.st_mode & stat.S_ISVTX:
        try:
            where.chmod(stat.S_IMODE(st.st_mode) & ~0o022)
            return None
        except OSError as err:
            return f"others may write it and it cannot be closed to them ({err.strerror})"
    if ours:
        return f"others may write it (chmod go-w {where} makes it yours only)"
    return "it belongs to another user"


def directory() -> tuple[pathlib.Path | None, str]:
    """(the cache directory a new process uses, where that choice comes from). A directory
    configured for JAX (`JAX_COMPILATION_CACHE_DIR`) is used as it is; `stickslip._jax`
    then leaves it alone."""
    jax_dir = os.environ.get("JAX_COMPILATION_CACHE_DIR", "").strip()
    if jax_dir:
        return pathlib.Path(jax_dir).expanduser(), "JAX_COMPILATION_CACHE_DIR (JAX's own)"
    where = own_directory()
    if where is None:
        return None, f"off (STICKSLIP_CACHE_DIR={os.environ.get('STICKSLIP_CACHE_DIR')!r})"
    if "STICKSLIP_CACHE_DIR" in os.environ:
        return where, "STICKSLIP_CACHE_DIR"
    return where, "default"


def _size(path: pathlib.Path) -> tuple[int, int]:
    """(bytes, files) under `path` (a file or a folder; 0 for neither)."""
    if path.is_file():
        return path.stat().st_size, 1
    total = count = 0
    for file in path.rglob("*") if path.is_dir() else ():
        try:
            if file.is_file():
                total += file.stat().st_size
                count += 1
        except OSError:  # removed meanwhile (a background compiler at work)
            pass
    return total, count


def _jax_entries(where: pathlib.Path) -> list[pathlib.Path]:
    return [p for p in where.iterdir() if p.name.endswith("-cache") or "-cache-" in p.name]


def info() -> dict:
    """What `stickslip cache info` reports, as plain data: the directory and why, its size,
    the traces, the executables and queued jobs per CPU kind (this machine's marked), JAX's
    own entries, and the traces shipped with the package with the library versions they
    were made with against the installed ones."""
    import importlib.metadata

    from . import _cpu

    where, why = directory()
    out: dict = {"directory": None if where is None else str(where), "source": why,
                 "cpu_kind": _cpu.KIND, "exists": bool(where and where.is_dir())}  # fmt: skip
    if out["exists"]:
        total, files = _size(where)
        out.update(bytes=total, files=files)
        out["traces"] = dict(zip(("bytes", "files"), _size(where / "stickslip-exported"),
                                 strict=True))  # fmt: skip
        kinds = {}
        executables = where / "stickslip-executable"
        for folder in sorted(executables.iterdir()) if executables.is_dir() else ():
            if folder.is_dir():
                size, n = _size(folder)
                queue = where / "stickslip-queue" / folder.name
                jobs = len(list(queue.glob("*.job"))) if queue.is_dir() else 0
                kinds[folder.name] = dict(bytes=size, files=n, queued=jobs,
                                          this_machine=folder.name == _cpu.KIND)  # fmt: skip
        out["executables"] = kinds
        size = count = 0
        for entry in _jax_entries(where):
            b, n = _size(entry)
            size, count = size + b, count + n
        out["jax_entries"] = dict(bytes=size, files=count)
    shipped = sorted(SHIPPED.glob("*.bin"))
    try:
        made_with = json.loads((SHIPPED / "versions.json").read_text())
    except (OSError, ValueError):
        made_with = {}
    installed = {}
    for dist in made_with or ("jax", "jaxlib", "diffrax", "equinox"):
        try:
            installed[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            installed[dist] = None
    out["shipped"] = dict(
        traces=len(shipped), bytes=sum(f.stat().st_size for f in shipped),
        made_with=made_with, installed=installed, usable=bool(made_with) and made_with == installed,
    )  # fmt: skip
    return out


def clear(where: pathlib.Path) -> tuple[int, int]:
    """Remove the compiled code under the cache directory `where`: stickslip's folders
    (traces, executables of every CPU kind, the background compiler's queue) and JAX's own
    entries; anything else there is left. Returns (bytes, files) removed."""
    total = files = 0
    for entry in [where / name for name in OURS] + _jax_entries(where):
        if not entry.exists():
            continue
        size, n = _size(entry)
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)
        total, files = total + size, files + n
    return total, files


def human(n: int) -> str:
    """Bytes as 1.2 MB (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n} B"  # pragma: no cover
