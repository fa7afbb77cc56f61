"""The CPU this process runs on, as the compiled code on disk is keyed by it (no JAX import:
the background compiler reads it before it takes its queue's lock).

XLA compiles for the CPU it runs on and loads an executable made for another CPU with only a
logged error (then the code may stop on an illegal instruction): `KIND` names the folder of
the executables (`stickslip._compile.executable_dir`), the background compiler's queue
(`stickslip._background.queue_dir`) and enters JAX's own cache keys (`stickslip._jax`).
"""

import functools
import hashlib
import os
import threading


def description(path: str = "/proc/cpuinfo") -> dict:
    """The first processor's entries in `path` (Linux's CPU description; `{}` where there
    is none): up to a blank line, or to an entry it has already given (the next processor's,
    where no blank line parts them)."""
    found = {}
    try:
        with open(path) as f:
            for line in f:
                name, colon, value = line.partition(":")
                name = name.strip()
                if not name or not colon:
                    if found and not line.strip():
                        break
                    continue
                if name in found:
                    break
                found[name] = value.strip()
    except (OSError, UnicodeDecodeError):
        pass
    return found


# The entries naming a CPU's maker, model and instruction sets: x86; ARM; POWER, s390x,
# RISC-V and others.
ENTRIES = (
    "vendor_id", "cpu family", "model", "flags",
    "CPU implementer", "CPU architecture", "CPU variant", "CPU part", "Features",
    "cpu", "revision", "features", "isa", "uarch", "model name",
)  # fmt: skip


def kind(described: dict) -> str:
    """The CPU kind XLA compiles for: its maker, model and instruction sets (from which LLVM
    picks the target and its features), from Linux's CPU description; elsewhere, what the
    system says (macOS's `sysctl`, Python's `platform`)."""
    if any(described.get(k) for k in ENTRIES):
        text = "\n".join(f"{k}={' '.join(sorted(described.get(k, '').split()))}" for k in ENTRIES)
    else:
        text = _elsewhere()
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _elsewhere() -> str:
    import platform

    text = f"{platform.system()} {platform.machine()} {platform.processor()}"
    if platform.system() == "Darwin":  # (the model, and Intel's instruction sets)
        import subprocess

        keys = ("machdep.cpu.brand_string", "machdep.cpu.features", "machdep.cpu.leaf7_features")
        try:
            said = subprocess.run(["sysctl", "-n", *keys], capture_output=True, timeout=5)
            text += " " + " ".join(said.stdout.decode(errors="replace").split())
        except (OSError, subprocess.SubprocessError):
            pass
    return text


DESCRIPTION = description()
KIND = kind(DESCRIPTION)


def has_avx512() -> bool:
    return "avx512f" in DESCRIPTION.get("flags", "").split()  # (not Linux: XLA's default)


@functools.cache
def usable_cores() -> int:
    """The cores this process may use: its affinity (a batch job's share of a node) where
    the system says, else the machine's count."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # (not Linux)
        return os.cpu_count() or 1


def on_two_threads(work, n: int) -> list:
    """`[work(i) for i in range(n)]`, the items shared between this thread and a second
    one where the process may use two cores: for independent items whose time is spent
    without Python's lock (NumPy, SciPy, compiled kernels), the same results in either
    thread (a measured trace's paths, halves of the shape fits). Where items raise, the
    lowest such item's exception is raised here (as a loop would raise it)."""
    if n == 1 or usable_cores() < 2:
        return [work(i) for i in range(n)]
    out: list = [None] * n
    failed: list = [None] * n
    order = iter(range(n))  # (next() under Python's lock: each item taken once)

    def run():
        for i in order:
            try:
                out[i] = work(i)
            except BaseException as err:  # (raised in the caller's thread)
                failed[i] = err

    other = threading.Thread(target=run, name="stickslip-work", daemon=True)
    other.start()
    run()
    other.join()
    for err in failed:
        if err is not None:
            raise err
    return out
