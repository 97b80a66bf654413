"""``jsc soak``: the realtime loop at 1 kHz for minutes with gains changed every second, or
(``--faults``) for an hour with a fault injected every minute; prints the figures and the
verdict, writes soak.json (wiring and printing only)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from joint_space_control.machine import describe


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc soak``."""
    p = subparsers.add_parser(
        "soak",
        help="soak run: realtime 1 kHz loop (--rate) for minutes, gains changed every "
        "second; memory growth, command safety, parameter updates; writes soak.json, non-zero "
        "exit on fail",
    )
    p.add_argument(
        "--minutes", type=float, default=None, help="run length [min] (10; with --faults 60)"
    )
    p.add_argument("--robot", default="iiwa", help="built-in robot (iiwa)")
    p.add_argument(
        "--controller",
        choices=("inverse_dynamics", "pd_gravity"),
        default="inverse_dynamics",
        help="controller law (inverse_dynamics)",
    )
    p.add_argument("--out", type=Path, default=Path("out/soak"), help="output dir")
    p.add_argument(
        "--faults",
        action="store_true",
        help="inject one fault every --period (default a minute; --minutes defaults to 60): "
        "every kind at least once, judged from the bags (docs/safety.md, Fault soak)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=1000.0,
        help="the plant's joint states and so the loop [Hz], a divisor of its 1 kHz physics "
        "(1000): less on a machine too slow to run the loop at 1 kHz beside the rest of the "
        "run (docs/safety.md, Fault soak)",
    )
    p.add_argument("--seed", type=int, default=0, help="--faults: the schedule's seed (0)")
    p.add_argument(
        "--period", type=float, default=60.0, help="--faults: seconds between faults (60)"
    )
    p.set_defaults(handler=_handle)


def _handle(args: argparse.Namespace) -> int:
    if args.faults:
        minutes = 60.0 if args.minutes is None else args.minutes
        return run_faults(
            args.out, minutes, args.period, args.seed, args.robot, args.controller, args.rate
        )
    minutes = 10.0 if args.minutes is None else args.minutes
    return run(args.out, minutes, args.robot, args.controller, args.rate)


def _num(value: Any, fmt: str = "{:.0f}") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return fmt.format(value)


def format_report(report: dict[str, Any]) -> str:
    """The soak figures as a plain-text table, then the criteria and the verdict."""
    lines = [
        f"soak {report['robot']} {report['controller']}: {report['duration_s'] / 60:.2f} min "
        f"realtime at {report['rate_hz']:g} Hz, warm-up {report['warmup_s']:g} s, "
        f"started {report['started_utc']}",
        f"machine: {describe(report['machine'])}, CPU steal "
        + _num(report.get("cpu_steal_fraction"), "{:.1%}"),
        "source: "
        + (
            f"{report['source']['commit'][:10]}"
            + (
                f" + uncommitted changes in {len(report['source']['changed_files'])} files"
                if report["source"]["changed_files"]
                else ""
            )
            if report.get("source")
            else "unknown"
        ),
        "",
        f"{'process':<30} {'RSS first':>10} {'start':>9} {'end':>9} {'max':>9} {'slope':>13}",
    ]
    for name, mem in report["memory"].items():
        mb = [_num(mem[k], "{:.1f}") for k in ("first_mb", "start_mb", "end_mb", "max_mb")]
        slope = _num(mem["slope_mb_per_min"], "{:+.3f}")
        lines.append(
            f"{name:<30} {mb[0]:>7} MB {mb[1]:>6} MB {mb[2]:>6} MB {mb[3]:>6} MB {slope:>6} MB/min"
        )
    ticks = "  ".join(f"{k} {_num(v)}" for k, v in report["ticks"].items())
    cmd, upd = report["commands"], report["parameter_updates"]
    lines += [
        "",
        f"ticks: {ticks}",
        f"sim_bridge ticks late (> 200 us): {_num(report['late'])}, "
        f"too late (> 1 ms): {_num(report['too_late'])}",
        f"effort commands checked: {cmd['commands']}, violations: {cmd['violations']} "
        f"(non-finite {cmd['non_finite']}, over limit {cmd['over_limit']}, unknown joints "
        f"{cmd['unknown_joints']}), largest |tau|/limit {cmd['max_effort_over_limit']:.3f}",
        "command delivery to the observer: first stamp "
        f"{_num(report['command_delivery']['first_stamp_s'], '{:.3f}')} s, longest gap "
        f"{_num(report['command_delivery']['longest_gap_between_arrivals_ms'], '{:.1f}')} ms, "
        "longest publication to arrival "
        f"{_num(report['command_delivery']['longest_publication_to_arrival_ms'], '{:.1f}')} ms",
        f"gain changes accepted: {upd['valid_accepted']}/{upd['valid_sent']}; invalid updates "
        f"rejected: {upd['invalid_rejected']}/{upd['invalid_sent']} (old values kept "
        f"{upd['old_values_kept_after_reject']})",
        "diagnostics received: "
        + ", ".join(f"{k} {v}" for k, v in report["diagnostics_received"].items())
        + "; WARN statuses: "
        + (", ".join(f"{k} {v}" for k, v in report["diagnostics_warnings"].items()) or "none"),
        "",
        "final /diagnostics (every numeric key, since the first tick where total.*):",
    ]
    for node, values in report["diagnostics"].items():
        lines.append(f"  {node}:")
        items = [f"{k}={_num(v, '{:g}')}" for k, v in values.items()]
        for k in range(0, len(items), 6):
            lines.append("    " + "  ".join(items[k : k + 6]))
    lines += ["", "criteria:"]
    for c in report["criteria"]:
        mark = {True: "PASS", False: "FAIL", None: "----"}[c["met"]]
        lines.append(f"  [{mark}] {c['name']}: {c['detail']}")
    lines.append(f"verdict: {'PASS' if report['passed'] else 'FAIL'}")
    return "\n".join(lines)


def run(out: Path, minutes: float, robot: str, law: str, rate: float = 1000.0) -> int:
    # deferred: the library (ROS, Pinocchio) loads only for this command, not for `jsc --help`
    from joint_space_control.lab.soaks.soak import CONTROLLERS, SoakOptions
    from joint_space_control.lab.soaks.soak import run as run_soak

    if law not in CONTROLLERS:
        print(f"jsc soak: error: unknown controller '{law}'", file=sys.stderr)
        return 2
    if minutes <= 0:
        print("jsc soak: error: --minutes must be > 0", file=sys.stderr)
        return 2
    try:
        options = SoakOptions(minutes=minutes, robot=robot, law=law, rate=rate)
    except ValueError as exc:
        print(f"jsc soak: error: --rate: {exc}", file=sys.stderr)
        return 2
    return _run_and_print(
        lambda: run_soak(out, options, _say), format_report, Path(out), "soak.json"
    )


def _say(message: str) -> None:
    print(message, flush=True)


def _run_and_print(run_soak: Any, format_report: Any, out: Path, *written: str) -> int:
    """Run a soak; print its report and what it wrote. Exit code: 0 passed, 1 failed or
    could not run (the reason in one line), 130 interrupted (its processes stopped)."""
    try:
        report = run_soak()
    except KeyboardInterrupt:
        print("jsc soak: interrupted; every process stopped", file=sys.stderr)
        return 130
    except (RuntimeError, TimeoutError, ValueError) as err:
        print(f"jsc soak failed: {' '.join(str(err).split())}", file=sys.stderr)
        return 1
    print()
    print(format_report(report))
    print("\nwritten: " + ", ".join(str(out / name) for name in written))
    return 0 if report["passed"] else 1


def format_fault_report(report: dict[str, Any]) -> str:
    """The fault soak's table per kind, then the criteria and the verdict."""
    o = report["options"]
    states = report["states"]
    lines = [
        f"soak with faults: {o['robot']} {o['controller']}, realtime "
        f"{o.get('rate_hz', 1000.0):g} Hz, {report['duration_s'] / 60:.2f} min, "
        f"{len(report['faults'])} faults (a fault every {o['period_s']:g} s, seed {o['seed']})",
        f"machine: {describe(report['machine'])}",
        "",
        report["by_kind_text"],
        "",
        f"states recorded {states['recorded']}, lost inside bags {states['lost_inside_bags']}, "
        f"between bags (recorder down) {states['lost_between_bags']}; applied efforts beyond "
        f"the limits {report['efforts_beyond_limits']} (peak |tau|/limit "
        f"{_num(report['peak_effort_over_limit'], '{:.3f}')}); controller commands "
        f"{report['commands']['commands']}, others refused by the plant's rules "
        f"{report['other_commands']}",
        "bags: " + ", ".join(f"{Path(b['path']).name} {b['status']}" for b in report["bags"]),
        "",
        report["cpu_text"],
        "",
        "criteria:",
    ]
    for c in report["criteria"]:
        mark = {True: "PASS", False: "FAIL", None: "----"}[c["met"]]
        lines.append(f"  [{mark}] {c['name']}: {c['detail']}")
    if not report["passed"]:  # what the nodes said: which loop slowed or alarmed, and when
        lines += ["", report["loops_text"], "", report["logged_text"]]
        failed = [c["name"] for c in report["criteria"] if c["met"] is False]
        lines.append("failed: " + "; ".join(failed))  # last, where a tail of the output is
    lines.append(f"verdict: {'PASS' if report['passed'] else 'FAIL'}")
    return "\n".join(lines)


def run_faults(
    out: Path,
    minutes: float,
    period: float,
    seed: int,
    robot: str,
    law: str,
    rate: float = 1000.0,
) -> int:
    from joint_space_control.lab.soaks.fault_soak import FaultSoakOptions
    from joint_space_control.lab.soaks.fault_soak import run as run_fault_soak

    if minutes <= 0 or period <= 0 or minutes * 60.0 < 1.5 * period:
        print(
            "jsc soak: error: --minutes and --period must be > 0, the run at least 1.5 periods",
            file=sys.stderr,
        )
        return 2
    try:
        options = FaultSoakOptions(
            minutes=minutes, period=period, seed=seed, robot=robot, law=law, rate=rate
        )
    except ValueError as exc:
        print(f"jsc soak: error: --rate: {exc}", file=sys.stderr)
        return 2
    return _run_and_print(
        lambda: run_fault_soak(out, options, _say),
        format_fault_report,
        Path(out),
        "soak.json",
        "soak.png",
    )
