"""`stickslip cache info` and `stickslip cache clear`: the compiled-code cache on disk."""

from __future__ import annotations

import json
import sys

import click

from ._common import EXIT_BAD_INPUT, handle_errors


@click.group()
def cache():
    """The compiled-code cache: where it is, how big, and emptying it.

    The simulator keeps what it compiles on disk, so a later run loads it instead of
    compiling again (STICKSLIP_CACHE_DIR sets the folder, `off` turns it off;
    STICKSLIP_COMPILE=reuse turns the background compiler off)."""


@cache.command()
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@handle_errors
def info(as_json: bool):
    """Where the cache is, its size, its executables per CPU kind and the shipped traces."""
    from .. import _cache

    report = _cache.info()
    if as_json:
        click.echo(json.dumps(report, indent=1))
        return
    h = _cache.human
    where = report["directory"]
    if where is None:
        click.echo(f"cache: {report['source']}: compiled code is not kept between runs")
    elif not report["exists"]:
        click.echo(f"cache: {where} ({report['source']}): empty (not created yet)")
    else:
        click.echo(f"cache: {where} ({report['source']})")
        click.echo(f"  size: {h(report['bytes'])} in {report['files']} files")
        t = report["traces"]
        click.echo(f"  traces (any CPU): {h(t['bytes'])} in {t['files']} files")
        if not report["executables"]:
            click.echo("  executables: none")
        for kind, e in report["executables"].items():
            mark = " (this machine)" if e["this_machine"] else ""
            queued = f", {e['queued']} queued for the background compiler" if e["queued"] else ""
            click.echo(
                f"  executables for CPU kind {kind}{mark}: {h(e['bytes'])} in {e['files']} "
                f"files{queued}"
            )
        j = report["jax_entries"]
        click.echo(f"  JAX's own entries: {h(j['bytes'])} in {j['files']} files")
    s = report["shipped"]
    made = ", ".join(f"{k} {v}" for k, v in s["made_with"].items()) or "unknown versions"
    if s["usable"]:
        state = "the installed versions: used"
    else:
        have = ", ".join(f"{k} {v}" for k, v in s["installed"].items())
        state = f"not used, other versions installed: {have}"
    click.echo(f"shipped traces: {s['traces']} ({h(s['bytes'])}), made with {made}; {state}")


@cache.command()
@handle_errors
def clear():
    """Remove the compiled code in the cache folder (traces, executables of every CPU kind,
    the background compiler's queue, JAX's own entries); other files there are left. The
    next run compiles again."""
    from .. import _cache

    where, why = _cache.directory()
    if where is None:
        click.echo(f"cache: {why}: nothing to clear")
        return
    if where.exists() and not where.is_dir():
        click.echo(f"error: cache: {where} ({why}) is not a folder", err=True)
        sys.exit(EXIT_BAD_INPUT)
    if not where.is_dir():
        click.echo(f"cache: {where} ({why}): empty, nothing to clear")
        return
    size, files = _cache.clear(where)
    click.echo(f"cache: removed {_cache.human(size)} in {files} files from {where}")
