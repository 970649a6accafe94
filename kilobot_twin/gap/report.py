"""report.md for the gap workflow, with plots (read from the report, drawn separately)."""

from __future__ import annotations

from pathlib import Path

import numpy as np



def _fmt(v) -> str:
    """A fitted nuisance as the report prints it: numbers to 3 significant digits, lists of them
    (a pixel grid's two steps) as x / y."""
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return " / ".join(_fmt(x) for x in v)
    return str(v)


def _white_noise_text(lags) -> str:
    """What the fitted heading-noise intensity is: white noise that wanders as much as the tracks
    between the summary's two lags (docs/gap_methods.md: coloured turn noise)."""
    return (f"sigma_omega is the white heading noise that makes the tracks wander as much as measured between "
            f"{lags[0]:.2g} and {lags[1]:.2g} s. Turn noise correlated over a second or two wanders less over such "
            f"lags: its long-run intensity is then higher (by 2-16 % at a correlation of 1-2 s, more under lighter "
            f"tracking noise), and the turn rates' excess from trial to trial is read as bias_trial_sd. Telling the "
            f"two apart takes about 700 robot-trials at a correlation of 2 s and 2 mm of tracking noise "
            f"(benchmarks/noise_colour.py).")


def _tracked_point_text(tp: dict) -> str:
    """What the named speed spread would take of the tracker (``workflow.tracked_point_offset``):
    a tracked point that far to the side of the rotation centre, and whether a point on the
    robot's body can be that far."""
    head = (f"The speed spread named ({100 * tp['speed_spread']:.2g} % of the speed) is also what robots alike in "
            f"speed would show, tracked at points {1000 * tp['offset_m']:.1f} mm (rms) to the side of their rotation "
            f"centres: at these turn rates (rms {tp['turn_rate_rms_rad_s']:.2g} rad/s) such a point moves at "
            f"v - omega r.")
    if tp.get("within_body", True):
        return (f"{head} The data cannot tell the two apart; where the tracked point may sit that far off the "
                f"centre, the spread may be the tracker's.")
    return (f"{head} That is beyond a Kilobot's body (radius {1000 * tp['body_radius_m']:.1f} mm), so no point "
            f"on the robot makes this spread: the robots differ in speed.")


def _removed(sh: dict) -> str:
    """The gap removed where the disagreement was, and whether naming reduced it at all."""
    lo, hi = sh.get("removed_ci95") or (None, None)
    if lo is None:
        return ""
    verdict = "reduced" if lo > 0 else "raised" if hi < 0 else "not clearly changed"
    return f"; gap removed {sh['removed']:.2f} (95 % CI {lo:.2f} .. {hi:.2f}): {verdict} by the named effects"


def _where(s: dict) -> list:
    """Lines of report.md that say where the gap is: each summary's parts, base -> final model
    (``gap_by_part``); and, when no test flagged anything yet the gap before is clearly above 0,
    which part holds most of it."""
    from .workflow import GAP_PARTS

    by = s.get("gap_by_part")
    if not by:
        return []
    lines = ["Where the gap is: each summary's held-out excess deviance, by part, base -> updated model "
             "(0 = as good as the model's noise; the gap is their mean):", "",
             "| summary | " + " | ".join(GAP_PARTS.values()) + " |", "|---" * (len(GAP_PARTS) + 1) + "|"]
    for c, parts in by.items():
        lines.append(f"| {c} | " + " | ".join(f"{parts[p][0]:.2f} -> {parts[p][1]:.2f}" for p in GAP_PARTS) + " |")
    shared = {c: (r, (s.get("shared_rounding_sd") or {}).get(c, 0.0)) for c, r in (s.get("shared_deviation") or {}).items() if r > 0}
    if shared:
        lines += ["", "The robots of a trial lie closer together than the model's independent robots would: they "
                  "share part of their deviation (" + ", ".join(f"{c} {r:.2f}" for c, (r, _) in shared.items())
                  + " of it). "
                  + ("The sensor's reading noise is too small to dither the ADC's rounding, so robots reading the "
                     "same sweep round it alike: the per trial level's spread takes that shared part (sd "
                     + ", ".join(f"{c} {_fmt(sd)}" for c, (_, sd) in shared.items()) + ")."
                     if any(sd > 0 for _, sd in shared.values()) else
                     "No rounding is shared here (the noise dithers it, or nothing is rounded): what the robots "
                     "share stays in the gap, or their model's spread is wider than theirs.")]
    lo = s["gap_before"]["ci95"][0]
    if not s["disagreements"] and lo is not None and lo > 0:
        c, p = max(((c, p) for c in by for p in GAP_PARTS), key=lambda cp: by[cp[0]][cp[1]][0])
        tests = ", ".join(s.get("tests", [])) or "none"
        lines += ["", f"No test flagged anything, yet the base misses the held-out trials by more than its noise "
                  f"(gap {s['gap_before']['value']:.2f}, 95 % CI {lo:.2f} .. {s['gap_before']['ci95'][1]:.2f}), "
                  f"most in {c}, {GAP_PARTS[p]} ({by[c][p][0]:.2f})"
                  + (": the swarm as a whole shifts from trial to trial by more than the model's noise makes it. "
                     f"None of the tests ({tests}) is of each trial's level, and "
                     "no effect of the library shifts a trial as a whole." if p == "level" else
                     f"; no test ({tests}) crossed its threshold.")]
    return lines + [""]


def _more_data(v: dict) -> str:
    """The detection sizes of more robots or trials (workflow.other_designs), as one clause."""
    d = v.get("at_other_designs")
    if not d:
        return ""
    return ("; detected with more data (the F test's theory, scaled from this dataset's size): "
            + ", ".join(f"{x['robots']} robots x {x['trials']} trials {x['detection_size']:.3g}" for x in d))


def _can_see(mde: dict) -> list:
    """report.md's lines for ``minimum_detectable``: each effect's size named and detected, or
    why none is stated, and the detection size with more robots or trials."""
    lines = []
    for eff, v in mde.items():
        if "why_none" in v:  # no size named for these data (workflow.none_stated), and why
            det = v.get("detection_size")
            lines.append(f"- {eff}: none stated: {v['why_none']}"
                         + (f"; detected {det:.3g} ({v['unit']})" if det is not None else "") + _more_data(v))
            continue
        if v.get("by") == "simulation":  # an effect of your own (workflow.simulated_detection)
            detected = (f"none up to {v['searched_to']:.3g}" if v["detection_size"] is None
                        else f"{'at most ' if v.get('at_most') else ''}{v['detection_size']:.3g}")
            lines.append(f"- {eff} (yours): detected {detected} ({v['unit']}), by simulating the twin with it "
                         f"({v['replicates']} datasets per size); named needs at least that (not simulated)")
            continue
        named, detected = (f"none up to {v['searched_to']:.3g}" if x is None else f"{x:.3g}"
                           for x in (v["size"], v["detection_size"]))
        if "best_power" in v:  # how near the search came (none at all: no size to point to)
            named += (f" (at most {100 * v['best_power']:.0f} % power, at {v['best_at']:.3g})" if v["best_power"] > 0
                      else " (named at none of the sizes searched)")
        lines.append(f"- {eff}: named {named}, detected {detected} ({v['unit']})" + _more_data(v))
    return lines


def write_markdown(out: Path, report: dict, residuals: list) -> Path:
    """report.md and one figure per dataset; ``residuals[j]``: per-robot held-out residuals of the
    base and the final model of dataset j (``before``, ``after``)."""
    from ..plots import pyplot, save

    plt = pyplot()
    lines = ["# Twin vs measurement", "",
             f"Named effects (in the order added): **{', '.join(report['named_effects']) or 'none'}**; "
             f"unexplained: **{report['unexplained']}**"
             + (f" (signals: {', '.join(report['unexplained_signals'])})" if report["unexplained_signals"] else ""), ""]
    mine = {k: v["source"] for k, v in report.get("library", {}).items() if v["source"] != "kilobot_twin"}
    if mine:
        lines += ["Candidates of your own beside the library's: " + ", ".join(f"{k} (`{v}`)" for k, v in mine.items()), ""]
    for j, s in enumerate(report["datasets"]):
        lines += [f"## {s['dataset']} ({s['kind']}, {len(s['robots'])} robots x {s['trials']} trials)", "",
                  f"- gap before: {s['gap_before']['value']:.2f} (95 % CI {s['gap_before']['ci95'][0]:.2f} .. {s['gap_before']['ci95'][1]:.2f})",
                  f"- gap after: {s['gap_after']['value']:.2f} (95 % CI {s['gap_after']['ci95'][0]:.2f} .. {s['gap_after']['ci95'][1]:.2f})",
                  f"- shrink where the disagreement was ({', '.join(s['gap_shrink']['summaries']) or 'nothing flagged'}; "
                  f"{s['gap_shrink']['before']:.2f} -> {s['gap_shrink']['after']:.2f}): {100 * s['gap_shrink']['value']:.0f} % "
                  + (f"(95 % CI {100 * s['gap_shrink']['ci95'][0]:.0f} .. {100 * s['gap_shrink']['ci95'][1]:.0f} %)"
                     if s['gap_shrink']['ci95'][0] is not None else "(95 % CI unbounded: the gap before is not clearly above 0)")
                  + _removed(s["gap_shrink"]),
                  f"- metric: {s['gap_before']['metric']}; computed on held-out trials (leave-one-trial-out)", ""]
        lines += _where(s)
        if s["disagreements"]:
            lines += ["| round | signal | robots | trials | z | p |", "|---|---|---|---|---|---|"]
        else:  # (a table of headers alone said as much, less plainly)
            lines.append(f"No test flagged a disagreement ({', '.join(s.get('tests') or []) or 'none run'}).")
        for d in s["disagreements"]:
            lines.append(f"| {d['round']} | {d['signal']} | {d['robots'][:8]} | {d['trials']} | {d['z']:.1f} | {d['p_value']:.2g} |")
        if s["steps"]:
            level = s["steps"][0]["score_vs_current"]["level"]
            lines += ["", f"| step | named | log-lik gain vs current (one-sided {100 * level:.0f} % bounds) | runner-up "
                      "| gain over it (95 % CI) | gap after |", "|---|---|---|---|---|---|"]
        for i, st in enumerate(s["steps"]):
            sc, ru = st["score_vs_current"], st["runner_up"]
            over = ("-" if ru["name"] is None else
                    f"{ru['loglik_gain_over_it']:.1f} ({ru['ci95'][0]:.1f} .. {ru['ci95'][1]:.1f})")
            lines.append(f"| {i + 1} | {st['name']} | {sc['loglik_gain']:.1f} ({sc['ci'][0]:.1f} .. {sc['ci'][1]:.1f}) | "
                         f"{ru['name'] or 'none'} | {over} | {st['gap_after']:.2f} |")
        for i, st in enumerate(s["steps"]):
            if st["runner_up"]["name"] is None:
                lines.append(f"\nStep {i + 1}: no other candidate scored on the same summaries competed with it, so no runner-up is shown.")
            elif st["runner_up"].get("why_this_one"):
                lines.append(f"\nStep {i + 1}: the runner-up shown is {st['runner_up']['why_this_one']}.")
            if st.get("set_aside"):
                lines.append(f"Not scored at step {i + 1}: {', '.join(st['set_aside'])} (accounts for none of the "
                             f"flagged signals: {', '.join(st['signals'])}).")
        nn = s.get("not_named")
        if nn:
            lines.append(f"\nRound {nn['round']} named nothing ({', '.join(nn['signals'])} stay unexplained): "
                         + (f"the best candidate, {nn['best']} (gain {nn['scores'][nn['best']]:.1f}, one-sided "
                            f"{100 * nn['level']:.0f} % bounds {nn['ci_gain'][0]:.1f} .. {nn['ci_gain'][1]:.1f}), is not "
                            f"named: {nn['why']}." if nn["best"] else f"{nn['why']}.")
                         + (f" Not scored: {', '.join(nn['set_aside'])} (they account for none of them)." if nn["set_aside"] else ""))
        if s.get("minimum_detectable"):
            lines += ["", "What this dataset can see: the smallest spread named with 80 % power (nothing named means "
                      "nothing larger), and the smallest the detection step alone flags with 80 % power:"]
            lines += _can_see(s["minimum_detectable"])
        tp = s.get("tracked_point")
        if tp:
            lines += ["", _tracked_point_text(tp)]
        if s.get("estimates"):
            lines += ["", "Per-robot estimates (model.yaml) and how closely they can follow the robots' true values "
                      "from these trials (expected correlation, also about their slope against the truth; "
                      "more trials raise it):"]
            for trait, v in s["estimates"].items():
                lines.append(f"- {trait}: expected r {v['expected_r']:.2f}")
        if s.get("scenario"):
            lines += ["", "Scenario fields the named effects fitted for the whole swarm (keys of a scenario file, "
                      "e.g. for `kilobot-twin run`): " + ", ".join(f"`{k}` {_fmt(v)}" for k, v in s["scenario"].items())]
        ci = s.get("nuisance_ci90") or {}
        lines += ["", "Nuisances fitted by the base model: " + ", ".join(
            f"{k} {_fmt(v)}" + (f" (90 % CI {_fmt(ci[k][0])} .. {_fmt(ci[k][1])})" if k in ci else "")
            for k, v in s.get("nuisances", {}).items())]
        if ci:
            lines += ["", "The intervals resample the robots (their trials kept together) and solve each resample "
                      "on the base fit's simulated map, its replicates resampled too: they say how far the robots "
                      "at hand pin each level, not how far another world's noise may differ from the twin's kind "
                      "of noise, and a level at 0 in every resample reads 0 .. 0. On another simulator's worlds "
                      "they held its truth in 82-90 %, less where its noise was not of the twin's kinds "
                      "(docs/gap_methods.md)."]
        lags = s.get("nuisances", {}).get("wander_lags_s")
        if lags:
            lines += ["", _white_noise_text(lags)]
        lines.append("")
        fig, axes = plt.subplots(1, 3, figsize=(14, 3.8))
        res = residuals[j]
        x = np.arange(len(s["robots"]))
        axes[0].bar(x - 0.2, res["before"], 0.4, label="base model")
        axes[0].bar(x + 0.2, res["after"], 0.4, label="updated model")
        step = max(1, int(np.ceil(len(x) / 20)))  # at most ~20 labels
        axes[0].set_xticks(x[::step], [str(r) for r in s["robots"]][::step])
        axes[0].set_xlabel("robot")
        axes[0].set_ylabel("held-out deviance per summary\n(z$^2$, linear beyond 4 sd)")
        axes[0].set_title("per-robot residuals")
        axes[0].legend()
        sh = s["gap_shrink"]
        groups = [("all summaries", (s["gap_before"]["value"], s["gap_before"]["ci95"]),
                   (s["gap_after"]["value"], s["gap_after"]["ci95"]))]
        if sh["summaries"]:
            groups.append((f"where flagged ({', '.join(sh['summaries'])})", (sh["before"], sh["before_ci95"]),
                           (sh["after"], sh["after_ci95"])))
        for g, (_, before, after) in enumerate(groups):
            for k, ((v, (lo, hi)), col, lab) in enumerate(((before, "tab:red", "base model"), (after, "tab:green", "updated model"))):
                axes[1].bar(g + (k - 0.5) * 0.38, v, 0.38, color=col, yerr=[[max(v - lo, 0)], [max(hi - v, 0)]], capsize=5,
                            label=lab if g == 0 else None)
        axes[1].set_xticks(range(len(groups)), [g[0] for g in groups], fontsize=8)
        axes[1].axhline(0, color="k", lw=0.5)
        axes[1].set_ylabel("gap (excess deviance per summary,\n0 = model noise)")
        axes[1].set_title(f"held-out gap, 95 % intervals; shrink {100 * sh['value']:.0f} %")
        axes[1].legend(fontsize=7)
        rounds = [(st["scores"], f"step {i + 1}: named {st['name']}", None) for i, st in enumerate(s["steps"])]
        if nn and nn["scores"]:
            rounds.append((nn["scores"], f"round {nn['round']}: nothing named", "//"))
        names = sorted({n for sc, _, _ in rounds for n in sc})  # one axis for every step
        width = 0.8 / max(len(rounds), 1)
        for i, (sc, lab, hatch) in enumerate(rounds):
            vals = [sc.get(n, np.nan) for n in names]
            axes[2].bar(np.arange(len(names)) + width * (i - (len(rounds) - 1) / 2), vals, width, label=lab,
                        hatch=hatch, edgecolor="k" if hatch else None)
        axes[2].set_xticks(np.arange(len(names)), names, rotation=20, fontsize=7)
        axes[2].axhline(0, color="k", lw=0.5)
        axes[2].set_xlabel("candidate effect")
        axes[2].set_ylabel("held-out log-likelihood gain")
        axes[2].set_title("candidate scores (held-out log-lik gain)")
        if rounds:
            axes[2].legend(fontsize=7)
        else:
            axes[2].text(0.5, 0.5, "nothing scored" if s["disagreements"] else "nothing flagged: nothing to score",
                         ha="center", va="center", transform=axes[2].transAxes)
        png = save(fig, out / f"gap_{j}.png", dpi=100)
        lines += ["", f"![gap]({png.name})", ""]
    lines += [f"Updated model: `{report['model']}` (load with `kilobot-twin run --traits` or the batch engine)."]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
