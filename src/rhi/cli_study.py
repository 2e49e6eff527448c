"""The `rhi study` commands (registered by `rhi.cli`): run a study with people, simulate it, analyse it."""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
from pathlib import Path

from rhi import cli_args as A
from rhi.errors import InvalidInput


def _protocol(name: str, seed: int | None = None):
    from rhi.study.protocol import load_protocol, parse_protocol

    p = load_protocol(name)
    if seed is None or seed == p.seed:
        return p
    if seed < 0:
        raise InvalidInput(f"--seed: must be >= 0, got {seed}")
    text, n = re.subn(r"(?m)^seed\s*=\s*\d+", f"seed = {seed}", p.text)
    if not n:
        text = f"seed = {seed}\n{text}"
    return parse_protocol(tomllib.loads(text), name=p.name, source=p.source, text=text)


def _durations(text: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in text.replace(",", " ").split())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected durations in seconds separated by commas, got {text!r}") from None
    if not vals or not all(v > 0 for v in vals):
        raise argparse.ArgumentTypeError(f"expected positive durations [s], got {text!r}")
    return vals


def _print_analysis(res) -> None:
    for table in res.tables:
        print(f"\n{table.title}")
        for r in table.rows:
            th = "" if r.thesis is None else f"thesis {float(r.thesis):>9.4g}"
            print(f"  {r.quantity:<58} {r.ours:>10.4g} {r.unit:<4} {th}")


def _simulate(args: argparse.Namespace) -> int:
    from rhi.design.executors import configure, shared
    from rhi.experiments.participants import simulated_study

    configure(executor=args.executor, workers=args.workers)
    p = _protocol(args.protocol, args.seed)
    if args.out and Path(args.out).exists() and any(Path(args.out).iterdir()):
        raise InvalidInput(f"--out: {args.out} is not empty")
    with shared():  # one pool (or Ray instance) for every map of the study, not one per map
        if p.kind == "path_following":
            return _simulate_task(args, p)
        kw = {} if args.durations is None else {"durations": args.durations}
        s = simulated_study(p, args.participants, out=args.out, weber_mean=args.weber_mean,
                            weber_sd=args.weber_sd, lapse=args.lapse, overdispersion=not args.fast, **kw)
    a = s.analysis
    print(f"rhi study simulate: {p.name}, {args.participants} simulated participants, seed {p.seed}, "
          f"{len(s.rows)} trials")
    for m, label in (("wf", "WF"), ("jnd", "JND"), ("pse", "PSE")):
        for c, sm in zip(a.devices, a.summary[m]):
            v = a.values[c] if m == a.measure else None
            spread = "" if v is None else f"  range {v.min():.4g}–{v.max():.4g}"
            print(f"  {label} {c:<10} mean {sm.mean:.4g}  std {sm.std:.4g}  median {sm.median:.4g}{spread}")
    print(f"  one-way ANOVA on WF: F({a.anova.df_between:g}, {a.anova.df_within:g}) = {a.anova.statistic:.4g}, "
          f"p = {a.anova.p_value:.4g}")
    print(f"  repeated-measures ANOVA on WF: F({a.anova_rm.df_between:g}, {a.anova_rm.df_within:g}) = "
          f"{a.anova_rm.statistic:.4g}, p = {a.anova_rm.p_value:.4g}")
    for t in a.paired:
        print(f"  paired t-test on WF {t.a} vs {t.b}: Holm-adjusted p = {t.p_adjusted:.4g}")
    print(f"  power of the one-way ANOVA at Table 3.3's WF effect with {args.participants} per condition "
          f"(alpha 0.05): {s.power:.3f}")
    if args.out:
        print(f"study folder: {args.out} (rhi study analyze {args.out})")
    return 0


def _simulate_task(args: argparse.Namespace, p) -> int:
    from rhi.experiments.participants import simulated_path_study

    s = simulated_path_study(p, args.participants, out=args.out)
    a = s.analysis
    print(f"rhi study simulate: {p.name}, {args.participants} simulated users (speeds "
          f"{s.speed.min():.4f}–{s.speed.max():.4f} m/s), seed {p.seed}, {len(s.rows)} runs")
    for m, summ in a.summary.items():
        for sm in summ:
            print(f"  {m} {sm.name:<6} mean {sm.mean:.4g}  std {sm.std:.4g}")
        an = a.anova[m]
        print(f"  one-way ANOVA on {m}: F({an.df_between:g}, {an.df_within:g}) = {an.statistic:.4g}, "
              f"p = {an.p_value:.4g}")
    print(f"  power of the one-way ANOVA at §5.5's effect on the execution time (F(2, 21) = 3.57) with "
          f"{args.participants} per condition (alpha 0.05): {s.power:.3f}")
    if args.out:
        print(f"study folder: {args.out} (rhi study analyze {args.out})")
    return 0


def _analyze(args: argparse.Namespace) -> int:
    from rhi.report.study import write_study_report

    out = args.out or str(Path(args.study_dir) / "analysis")
    path, res = write_study_report(args.study_dir, out, overdispersion=not args.fast)
    _print_analysis(res)
    print(f"\nreport: {path}\nnumbers: {path.parent / 'results.json'}")
    return 0


def _fields(items: list[str] | None) -> dict[str, str]:
    out = {}
    for text in items or []:
        k, sep, v = text.partition("=")
        if not sep or not k:
            raise InvalidInput(f"--field: expected NAME=VALUE, got {text!r}")
        out[k.strip()] = v.strip()
    return out


def _run(args: argparse.Namespace) -> int:
    from rhi.study.pages import serve_session

    return serve_session(args.protocol, args.participant, study_dir=args.study, link=args.link,
                         fields=_fields(args.field), host=args.host, port=args.port, mouse=args.mouse,
                         rate=args.rate, out=sys.stdout)


def add_commands(sub) -> None:
    """Register `rhi study run|simulate|analyze` on the `rhi` command's subparsers."""
    st = sub.add_parser("study", help="user studies with people: run a protocol, simulate it, analyse it")
    ss = st.add_subparsers(dest="study_command", required=True)
    r = ss.add_parser("run", help="run a participant's session: participant and experimenter pages in the browser")
    r.add_argument("protocol", help="a protocol TOML file or a shipped one (ch3_stiffness_2afc, ch5_path_following)")
    r.add_argument("--participant", required=True, help="the participant's id (the folder's name)")
    r.add_argument("--study", default="study", help="the study folder (default: ./study)")
    r.add_argument("--link", default="sim", help="sim (simulated device) or udp://HOST:PORT (a device server)")
    r.add_argument("--field", action="append", help="a declared participant field NAME=VALUE (repeatable)")
    r.add_argument("--host", default="127.0.0.1", help="address of the pages (default 127.0.0.1)")
    r.add_argument("--port", type=int, default=8090, help="port of the pages (default 8090; 0: any free port)")
    r.add_argument("--mouse", action="store_true", help="dry run: the mouse is the hand on the simulated device "
                   "(drag on the experimenter page's hand pad; for path following, on the participant's canvas)")
    r.add_argument("--rate", type=A.rate, default=1000.0, help="control rate [Hz] (default 1000)")
    r.set_defaults(func=_run)
    s = ss.add_parser("simulate", help="simulated participants run the protocol end to end (no browser): "
                      "expected JND/WF spread and the ANOVA's power")
    s.add_argument("protocol")
    s.add_argument("--participants", type=int, default=10, help="simulated participants (default 10)")
    s.add_argument("--seed", type=int, help="the study's seed (default: the protocol's)")
    s.add_argument("--out", help="write the participant folders here (then `rhi study analyze OUT`)")
    s.add_argument("--weber-mean", type=float, default=0.08, help="mean intrinsic Weber fraction (default 0.08)")
    s.add_argument("--weber-sd", type=float, default=0.02, help="its s.d. (default 0.02)")
    s.add_argument("--lapse", type=float, default=0.0, help="lapse rate of the answers (default 0)")
    s.add_argument("--durations", type=_durations, help="stroke durations of the simulated hand's lookup [s], "
                   "e.g. 0.7,1.4 (default: ch3.psychophysics's 0.6,0.9,1.3,2.0)")
    s.add_argument("--executor", choices=("local", "serial", "ray"), default="local",
                   help="where simulations and fits run (default: the local process pool)")
    s.add_argument("--workers", type=int, help="processes of the local pool")
    s.add_argument("--fast", action="store_true", help="psignifit without overdispersion (about twice as fast)")
    s.set_defaults(func=_simulate)
    a = ss.add_parser("analyze", help="analyse a study folder into a report (psignifit, PSE, JND, WF, ANOVA)")
    a.add_argument("study_dir")
    a.add_argument("--out", help="report folder (default: STUDY_DIR/analysis)")
    a.add_argument("--fast", action="store_true", help="psignifit without overdispersion")
    a.set_defaults(func=_analyze)
