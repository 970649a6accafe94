"""The ``kilobot-twin`` command. Each verb is a plain function; ``main`` only parses and reports.

Bad input ends with one line on stderr (``kilobot-twin: error: FIELD: problem; fix``) and
exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from datetime import datetime, timezone
from pathlib import Path

from . import __version__
from .errors import ConfigError
from .outputs import CreatedDirs, check_out_dir, check_out_file


# --- verbs as plain functions ------------------------------------------------------------

def simulate(config: str, out: str | None = None, traits: str | None = None, seed: int | None = None,
             runs: int | None = None, robots: int | None = None, workers: int | None = None,
             parquet: bool = False, progress: bool = True, scheduler: str | None = None) -> dict:
    """Run one configuration file (see :mod:`kilobot_twin.config`) and write its results.

    ``scheduler``: ``local:N`` or ``tcp://HOST:PORT`` runs the campaign on a Dask cluster."""
    from .batch import run_campaign
    from .config import load_config

    out = out or str(Path("results") / (Path(config).stem + ".npz"))
    check_out_file(out)
    cfg = load_config(config, traits_path=traits, seed=seed, runs=runs, n_robots=robots)
    _connect(scheduler)
    result = run_campaign(cfg, out=out, workers=workers, progress=progress, parquet=parquet,
                          desc=Path(config).stem, scheduler=scheduler)
    result["path"] = out
    return result


def _connect(scheduler: str | None) -> None:
    """Reach the Dask scheduler before anything is written (a one-line error if it is not there)."""
    if scheduler is not None:
        from .batch.cluster import client

        client(scheduler)


def draw_traits(population: str, out: str, seed: int | None = None, robots: int | None = None) -> Path:
    """Draw a swarm from a population file (``population: {...}``) and save it as robots. The seed
    is ``seed``, else the file's ``seed:``, else 0; a file whose own seed differs from ``seed`` is
    refused (the file's would win, and ``--seed`` would do nothing)."""
    from .core.traits import load_yaml, save_swarm, swarm_from_dict

    check_out_file(out)
    doc = load_yaml(population)  # read once: its seed is checked, then it is drawn
    own = doc.get("seed") if isinstance(doc, dict) else None
    if seed is not None and own is not None and own != seed:
        raise ConfigError("--seed", f"{population} sets its own seed: {own!r}, which the draw takes over --seed {seed}",
                          "leave out --seed, or remove seed: from the file")
    sw = swarm_from_dict(doc, seed=0 if seed is None else seed, n=robots, source=str(population))
    save_swarm(sw, out)
    return Path(out)


def check_traits(path: str) -> int:
    """Validate a traits file; returns the number of robots."""
    from .core.traits import load_swarm

    return len(load_swarm(path))


def experiment(name: str, out: str = "out/experiments", preset: str = "paper", quick: bool = False, seed: int = 2023,
               workers: int | None = None, progress: bool = True, scheduler: str | None = None):
    """Run one of the paper's experiments, save its arrays and plots, return its outcome."""
    from .experiments import Settings, run_experiment

    check_out_dir(out)
    settings = Settings(preset, quick, seed, workers, progress, scheduler)
    _connect(scheduler)
    return run_experiment(name, settings, out)


def reproduce(out: str = "out/reproduce", preset: str = "paper", quick: bool = False, seed: int = 2023,
              workers: int | None = None, progress: bool = True, scheduler: str | None = None) -> dict:
    """Run all eight experiments and write DIR/report.md (+ report.json, figures, arrays)."""
    from .experiments.report import reproduce as _reproduce

    check_out_dir(out)
    _connect(scheduler)
    return _reproduce(out, preset, quick, seed, workers, progress, scheduler)


def synth(kind: str, hidden: str, out: str, robots: int | None = None, trials: int | None = None, seed: int = 0,
          heading_noise_tau_s: float = 0.0, effect_scale: float = 1.0) -> dict:
    """Write a measured-v1 dataset from the twin with the named effects hidden in it (+ truth.json)."""
    from .gap.synth import synth as _synth

    check_out_dir(out, new=True)
    return _synth(kind, hidden, out, robots, trials, seed, heading_noise_tau_s=heading_noise_tau_s,
                  effect_scale=effect_scale)


def gap(data: list[str], out: str, model: str | None = None, seed: int = 0, quiet: bool = False,
        effects: list[str] | None = None) -> dict:
    """Hold the twin against measured data: detect, name, add, show the gap shrink. ``effects``:
    Python files whose Effect subclasses join the library's candidates."""
    from .gap.effects import LIBRARY, frame_in, load_effects
    from .gap.workflow import GapSettings, run_gap

    check_out_dir(out)
    if any(Path(out).absolute() == Path(d).absolute() for d in data):
        raise ConfigError("--out", f"{out} is one of the data folders", "give a separate folder for the report")
    library = dict(LIBRARY)
    for f in effects or []:
        library.update(load_effects(f, taken=library))
    try:
        return run_gap(data, out, model, GapSettings(seed=seed, library=library), log=(lambda *a: None) if quiet else print)
    except ConfigError:
        raise
    except Exception as exc:  # raised in a user's effect: one line, where in their file
        mine = [(f, fr) for f in effects or [] if (fr := frame_in(exc, f)) is not None]
        if not mine:
            raise
        f, fr = mine[-1]
        raise ConfigError("--effects", f"{f} line {fr.lineno} ({fr.name}) raised {type(exc).__name__}: {exc}",
                          "fix the effect") from None


def demo(out: str = "out/demo", quick: bool = False, workers: int | None = None, progress: bool = True) -> dict:
    """The main job: a phototaxis campaign on embedded defaults, with a plot and a summary."""
    from .demo import run_demo

    check_out_dir(out)
    return run_demo(out, quick=quick, workers=workers, progress=progress)


def run(scenario: str = "phototaxis", robots: int = 10, duration: float = 20.0, seed: int = 0, mode: str = "lockstep",
        traits: str | None = None, out: str = "bags/run", timeout: float | None = None, echo=None, swarms: int = 1):
    """Start world, swarm(s), analysis and recorder as processes; returns the run report (bag finalised)."""
    from .ros.launcher import run_twin

    return run_twin(scenario, robots, duration, seed, mode, traits, out, timeout_s=timeout, echo=echo, swarms=swarms)


def bag_repair(path: str) -> dict:
    """Recover every intact chunk of a damaged or unfinalised bag; rewrite summary and metadata.yaml."""
    from .recording.bag import repair_bag

    return repair_bag(path)


def bag_info(path: str) -> dict:
    """Messages per topic (those readable) and the kilobot_twin metadata of a bag."""
    from .recording.bag import BagReader

    reader = BagReader(path)
    log_ns = [m.log_time_ns for m in reader.messages()]
    files = [f for f in Path(path).iterdir() if f.is_file()]
    return {"counts": reader.counts(), "metadata": reader.metadata(), "skipped": reader.note,
            "messages": len(log_ns), "size_bytes": sum(f.stat().st_size for f in files),
            "log_start_ns": min(log_ns, default=None), "log_end_ns": max(log_ns, default=None)}


def _metadata_value(v: str, width: int = 60) -> str:
    """A metadata value for one line: as it is if short, else its kind and size (and keys)."""
    if len(v) <= width:
        return v
    try:
        doc = json.loads(v)
    except ValueError:
        return v[: width - 3] + "..."
    keys = f": {', '.join(list(doc)[:6])}{', ...' if len(doc) > 6 else ''}" if isinstance(doc, dict) else ""
    return f"<JSON {type(doc).__name__}, {len(v)} chars{keys}>"


def view(source: str, out: str | None = None, spawn: bool = False, point: int = 0, run: int = 0) -> dict:
    """A bag (or a results .npz with trajectories) -> a Rerun recording NAME.rrd with its blueprint."""
    from .recording.swarm_data import load_source
    from .viewer.rerun_view import write_rrd

    rec = load_source(source, point=point, run=run)
    src = Path(source)
    out = out or str(src.with_suffix(".rrd") if src.suffix == ".npz" else src.parent / f"{src.name}.rrd")
    res = write_rrd(rec, out, spawn=spawn)
    res.update(robots=rec.n_robots, steps=rec.n_steps)
    return res


def replay(bag: str, rate: float = 1.0, loop: bool = False, topics: list[str] | None = None,
           wait_for_subscribers: float = 0.0) -> dict:
    """Publish every recorded message of a bag on its topic and type, in recorded time (and /clock)."""
    from .nodes.replay import replay_bag

    return replay_bag(bag, rate=rate, loop=loop, topics=topics, wait_for_subscribers_s=wait_for_subscribers)


def import_measured(dataset: str, out: str) -> dict:
    """A measured dataset (measured-v1 folder) -> a bag with the twin's topics and types."""
    from .recording.importer import import_dataset

    return import_dataset(dataset, out)


# --- argument parsing -----------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage dump), exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="kilobot-twin", description="A digital twin of a Kilobot swarm of individuals.")
    p.add_argument("--version", action="version", version=f"kilobot-twin {__version__}")
    sub = p.add_subparsers(dest="verb", required=True, metavar="VERB", parser_class=_Parser)

    s = sub.add_parser("simulate", help="run one configuration (scenario + swarm + Monte Carlo plan) from YAML")
    s.add_argument("config", help="run configuration YAML (see config/*.yaml)")
    s.add_argument("--out", help="results file (.npz); default results/<config>.npz")
    s.add_argument("--traits", help="traits YAML overriding the config's swarm")
    s.add_argument("--seed", type=_seed)
    s.add_argument("--runs", type=_positive_int)
    s.add_argument("--robots", type=_positive_int, help="number of robots (population configs)")
    s.add_argument("--workers", type=_positive_int, help="threads or processes (default: all cores)")
    s.add_argument("--scheduler", type=_scheduler, help=_SCHEDULER_HELP)
    s.add_argument("--parquet", action="store_true", help="also write a long-format .parquet table")
    s.add_argument("--no-progress", action="store_true")

    d = sub.add_parser("demo", help="the main job: a phototaxis campaign with a plot and a summary")
    d.add_argument("--out", default="out/demo")
    d.add_argument("--quick", action="store_true", help="fewer runs (seconds instead of a minute)")
    d.add_argument("--workers", type=_positive_int)
    d.add_argument("--no-progress", action="store_true")

    from .experiments import EXPERIMENTS
    from .experiments.common import PRESET_NAMES

    e = sub.add_parser("experiment", help="run one of the paper's experiments (arrays + plot + checks)")
    e.add_argument("name", choices=list(EXPERIMENTS))
    e.add_argument("--out", default="out/experiments")
    e.add_argument("--preset", choices=PRESET_NAMES, default="paper")
    e.add_argument("--quick", action="store_true")
    e.add_argument("--seed", type=_seed, default=2023)
    e.add_argument("--workers", type=_positive_int)
    e.add_argument("--scheduler", type=_scheduler, help=_SCHEDULER_HELP)
    e.add_argument("--no-progress", action="store_true")

    r = sub.add_parser("reproduce", help="run all eight experiments and write a paper-vs-ours report")
    r.add_argument("--out", default="out/reproduce")
    r.add_argument("--preset", choices=PRESET_NAMES, default="paper")
    r.add_argument("--quick", action="store_true", help="reduced runs (under 2 minutes)")
    r.add_argument("--seed", type=_seed, default=2023)
    r.add_argument("--workers", type=_positive_int)
    r.add_argument("--scheduler", type=_scheduler, help=_SCHEDULER_HELP)
    r.add_argument("--no-progress", action="store_true")

    sy = sub.add_parser("synth", help="write a measured dataset from the twin with hidden effects (+ truth.json)")
    sy.add_argument("--kind", required=True, choices=["motion", "light_sweep", "blink"])
    sy.add_argument("--hidden", default="none", help="none, or a comma list of effects (see kilobot_twin/gap/synth.py)")
    sy.add_argument("--robots", type=_positive_int)
    sy.add_argument("--trials", type=_positive_int)
    sy.add_argument("--seed", type=_seed, default=0)
    sy.add_argument("--heading-noise-tau", type=_correlation_time, default=0.0, metavar="S",
                    help="motion: correlation time of every robot's turn-rate noise, s (default 0: white)")
    sy.add_argument("--effect-scale", type=_effect_scale, default=1.0, metavar="F",
                    help="the hidden effects' size (spread over the robots, a floor's slope) x F (default 1: synth.py's HIDDEN sizes)")
    sy.add_argument("--out", required=True)

    g = sub.add_parser("gap", help="twin vs measurement: find the disagreement, name the effect, show the gap shrink")
    g.add_argument("data", nargs="+", help="measured datasets (measured-v1 folders) or bags")
    g.add_argument("--model", help="base model (traits YAML with robots:); default: the paper's Eq. 4 fitted to the data")
    g.add_argument("--out", required=True)
    g.add_argument("--seed", type=_seed, default=0)
    g.add_argument("--effects", action="append", metavar="FILE.py",
                   help="a Python file of your own effects (Effect subclasses) to add to the library's candidates; "
                        "repeatable (see docs/examples/floor_tilt.py)")
    g.add_argument("--quiet", action="store_true")

    t = sub.add_parser("traits", help="draw or check robot traits files")
    tsub = t.add_subparsers(dest="traits_verb", required=True, metavar="ACTION", parser_class=_Parser)
    td = tsub.add_parser("draw", help="draw a swarm from a population file and save it per robot")
    td.add_argument("population")
    td.add_argument("--out", required=True)
    td.add_argument("--seed", type=_seed, help="the draw's seed (default: the file's seed:, else 0)")
    td.add_argument("--robots", type=_positive_int)
    tc = tsub.add_parser("check", help="validate a traits file")
    tc.add_argument("path")

    r = sub.add_parser("run", help="run the ROS 2 twin (world, swarm, analysis, recorder) into an MCAP bag")
    r.add_argument("--scenario", default="phototaxis", help="straight, phototaxis, random_walk, blink, sync or a scenario YAML file")
    r.add_argument("--robots", type=_positive_int, default=10)
    r.add_argument("--duration", type=float, default=20.0, help="simulated seconds")
    r.add_argument("--seed", type=_seed, default=0)
    r.add_argument("--mode", default="lockstep", help="lockstep (deterministic, as fast as possible) or realtime")
    r.add_argument("--traits", help="traits YAML (robots: or population:); default: a drawn population")
    r.add_argument("--out", default="bags/run", help="bag directory bags/NAME")
    r.add_argument("--timeout", type=float, help="give up if the world is not done after this many wall seconds")
    r.add_argument("--swarms", type=_positive_int, default=1,
                   help="swarm processes, each owning a block of the robot ids (uncoupled scenarios)")

    b = sub.add_parser("bag", help="inspect or repair recorded bags")
    bsub = b.add_subparsers(dest="bag_verb", required=True, metavar="ACTION", parser_class=_Parser)
    br = bsub.add_parser("repair", help="recover every complete chunk of a bag whose recorder was killed")
    br.add_argument("path")
    bi = bsub.add_parser("info", help="messages per topic and run metadata")
    bi.add_argument("path")

    rp = sub.add_parser("replay", help="publish a bag again on its topics, in recorded time (with /clock)")
    rp.add_argument("bag", help="bags/NAME")
    rp.add_argument("--rate", type=float, default=1.0, help="speed factor (1 = as recorded, 10 = ten times faster)")
    rp.add_argument("--loop", action="store_true", help="start again at the end (until Ctrl-C)")
    rp.add_argument("--topics", nargs="+", help="only these topics (exact names, or prefixes ending in / or *)")
    rp.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                    help="wait up to S seconds until every topic has a subscriber (e.g. a recorder)")

    im = sub.add_parser("import", help="turn a measured dataset (measured-v1) into a bag with the twin's topics")
    im.add_argument("dataset", help="folder with meta.yaml and observations.csv")
    im.add_argument("--out", required=True, help="bag directory bags/NAME")

    v = sub.add_parser("view", help="convert a bag (or a results .npz with trajectories) to a Rerun recording")
    v.add_argument("source", help="bags/NAME or results.npz")
    v.add_argument("--out", help="recording file (default: NAME.rrd next to the source)")
    v.add_argument("--spawn", action="store_true", help="also open a Rerun viewer")
    v.add_argument("--point", type=int, default=0, help="results .npz: grid point index")
    v.add_argument("--run", type=int, default=0, help="results .npz: Monte Carlo run")
    return p


_SCHEDULER_HELP = ("run campaigns on Dask: local:N (a local cluster of N worker processes) or tcp://HOST:PORT "
                   "(a running scheduler); default: this machine's cores")


def _scheduler(text: str) -> str:
    from .batch.cluster import parse_scheduler

    try:
        parse_scheduler(text)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("scheduler: ")) from None
    return text


def _checked_float(text: str, check, expected: str) -> float:
    """``text`` as a float passed through the library's ``check`` (which raises ConfigError), as
    an argparse type: bad input is one line naming the argument."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
    try:
        return check(v)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(f"{exc.problem}; {exc.fix}") from None


def _correlation_time(text: str) -> float:
    """A turn-rate noise correlation time, checked as the trait ``heading_noise_tau`` is."""
    from .core.traits import traits_from_mapping

    return _checked_float(text, lambda v: traits_from_mapping({"heading_noise_tau": v}).heading_noise_tau,
                          "a time in seconds")


def _effect_scale(text: str) -> float:
    """A factor on the hidden effects' spread, checked as ``synth`` checks it."""
    from .gap.synth import check_effect_scale

    return _checked_float(text, check_effect_scale, "a number above 0")


def _integer_from(minimum: int, expected: str):
    """An argparse type: an integer >= ``minimum``, else one line saying ``expected``."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {v}")
        return v
    return parse


_positive_int = _integer_from(1, "a positive integer")
_seed = _integer_from(0, "an integer >= 0")  # NumPy's seed sequences take no negative seeds


def main(argv=None) -> int:
    """Parse, run the verb, report. A bag read in part (damaged) is said in one line after the
    verb's output (``warning: ...``), or joins the one error line if the verb could not go on."""
    import warnings

    from .recording.bag import BagDamageWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BagDamageWarning)
        code = _main(argv, caught)
    for w in caught:   # other warnings are shown as Python would
        if not issubclass(w.category, BagDamageWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    if code != ConfigError.exit_code and _damage(caught):
        print(f"kilobot-twin: warning: {_damage(caught)}", file=sys.stderr)
    return code


def _damage(caught) -> str:
    """The notes of the bags read in part, from the recorded warnings."""
    from .recording.bag import BagDamageWarning

    notes = []
    for w in caught:
        if issubclass(w.category, BagDamageWarning) and str(w.message) not in notes:
            notes.append(str(w.message))
    return " | ".join(notes)


def _main(argv=None, caught=()) -> int:
    args = _parser().parse_args(argv)
    # On bad input a verb must leave nothing behind: folders it created and left empty go.
    created = CreatedDirs(getattr(args, "out", None))
    try:
        if args.verb == "simulate":
            res = simulate(args.config, args.out, args.traits, args.seed, args.runs, args.robots, args.workers,
                           args.parquet, not args.no_progress, args.scheduler)
            meta = res["meta"]
            print(f"wrote {res['path']}: {len(res['points'])} grid point(s) x {meta['runs']} run(s) x "
                  f"{len(res['swarm'])} robot(s), {meta['robot_steps'] / meta['elapsed_s'] / 1e6:.1f} M robot-steps/s")
        elif args.verb == "demo":
            res = demo(args.out, args.quick, args.workers, not args.no_progress)
            for p, s in res["summary"]["per_p_right"].items():
                print(f"{p}: mean cost at bias 0 {s['cost_at_zero_bias_m']:.2f} m, best {s['best_cost_m']:.2f} m at bias "
                      f"{s['best_bias']:+.3f}, R_acc {s['R_acc']} (biases on the paper's axis)")
            if res.get("twin"):
                from .demo import rerun_command

                print(f"twin bag: {res['twin']['bag']}\nrerun recording: {res['twin']['rrd']} "
                      f"(open: make view, or {rerun_command(res['twin']['rrd'])})")
            print(f"plot: {res['plot']}\nsummary: {res['summary_path']}\nthis run: {res['run_dir']} "
                  f"({Path(args.out) / 'latest'} points at it)")
        elif args.verb == "experiment":
            o = experiment(args.name, args.out, args.preset, args.quick, args.seed, args.workers, not args.no_progress,
                           args.scheduler)
            for c in o.checks:
                print(f"[{'met' if c.met else 'NOT MET'}] Fig. {c.figure}: {c.fact}: paper {c.paper}, ours {c.ours}"
                      + (f" ({c.note})" if c.note else ""))
            print(f"{sum(c.met for c in o.checks)} of {len(o.checks)} checks met")
            print("\n".join(["plots:"] + o.plots + [f"data: {o.meta['data']}"]))
        elif args.verb == "reproduce":
            doc = reproduce(args.out, args.preset, args.quick, args.seed, args.workers, not args.no_progress,
                            args.scheduler)
            print(f"{doc['met']} of {doc['total']} checks met in {doc['elapsed_s']:.0f} s; report: {args.out}/report.md")
        elif args.verb == "synth":
            truth = synth(args.kind, args.hidden, args.out, args.robots, args.trials, args.seed, args.heading_noise_tau,
                          args.effect_scale)
            print(f"wrote {args.out} ({truth['kind']}, hidden: {', '.join(truth['hidden']) or 'none'})")
        elif args.verb == "gap":
            rep = gap(args.data, args.out, args.model, args.seed, args.quiet, args.effects)
            print(f"named: {', '.join(rep['named_effects']) or 'none'}; unexplained: {rep['unexplained']}"
                  + (f" ({', '.join(rep['unexplained_signals'])})" if rep["unexplained_signals"] else ""))
            print(f"gap {rep['gap_before']['value']:.2f} -> {rep['gap_after']['value']:.2f}; report: {args.out}/report.md")
        elif args.verb == "traits":
            if args.traits_verb == "draw":
                print(f"wrote {draw_traits(args.population, args.out, args.seed, args.robots)}")
            else:
                print(f"{args.path}: {check_traits(args.path)} robot(s), valid")
        elif args.verb == "run":
            rep = run(args.scenario, args.robots, args.duration, args.seed, args.mode, args.traits, args.out,
                      args.timeout, echo=lambda line: print(line, file=sys.stderr), swarms=args.swarms)
            print(rep.text())
            if rep.interrupted:
                return 130
            return 0 if rep.ok else 1
        elif args.verb == "bag":
            if args.bag_verb == "repair":
                res = bag_repair(args.path)
                if res["intact"]:
                    print(f"{args.path} is intact ({res['messages']} messages in {res['chunks']} chunk(s)); nothing to repair")
                else:
                    print(f"repaired {args.path}: {res['messages']} messages in {res['chunks']} intact chunk(s) on "
                          f"{res['channels']} topic(s) recovered; damaged file kept as {res['damaged']}\n"
                          f"skipped: {res['skipped'] or 'nothing'}")
            else:
                info = bag_info(args.path)
                span = ""
                if info["log_start_ns"] is not None:
                    t0, t1 = (datetime.fromtimestamp(t / 1e9, timezone.utc) for t in (info["log_start_ns"], info["log_end_ns"]))
                    span = (f"; log time {(info['log_end_ns'] - info['log_start_ns']) / 1e9:.3f} s, "
                            f"{t0:%Y-%m-%d %H:%M:%S} .. {t1:%H:%M:%S} UTC")
                print(f"bag: {args.path}  ({info['size_bytes'] / 1e6:.2f} MB on disk; {info['messages']} messages on "
                      f"{len(info['counts'])} topics{span})")
                for topic, n in sorted(info["counts"].items()):
                    print(f"{topic:<40} {n}")
                for name, meta in info["metadata"].items():
                    print(f"metadata {name}: " + "; ".join(f"{k}={_metadata_value(v)}" for k, v in sorted(meta.items())))
        elif args.verb == "replay":
            res = replay(args.bag, args.rate, args.loop, args.topics, args.wait_for_subscribers)
            print(f"replayed {res['messages']} messages on {res['topics']} topics in {res['wall_s']:.2f} s; timing error "
                  f"p50 {res.get('err_p50_ms', 0):.3f} ms, p99 {res.get('err_p99_ms', 0):.3f} ms")
        elif args.verb == "import":
            res = import_measured(args.dataset, args.out)
            n = sum(res["counts"].values())
            print(f"wrote {res['path']}: {res['kind']} data of {res['robots']} robot(s), {len(res['trials'])} trial(s), "
                  f"{n} messages on {len(res['counts'])} topics")
        elif args.verb == "view":
            res = view(args.source, args.out, args.spawn, args.point, args.run)
            print(f"wrote {res['path']}: {res['robots']} robots x {res['steps']} samples in {res['total_s']:.2f} s")
        return 0
    except ConfigError as exc:
        created.remove_empty()
        note = _damage(caught)
        print(f"kilobot-twin: error: {exc}" + (f" [bag read in part: {note}]" if note and note not in str(exc) else ""),
              file=sys.stderr)
        return ConfigError.exit_code
    except KeyboardInterrupt:
        print("kilobot-twin: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
