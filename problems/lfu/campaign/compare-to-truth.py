#!/usr/bin/env python3
"""Compares a campaign's calibrated values with each test's own truth.

    python3 problems/lfu/campaign/compare-to-truth.py [CAMPAIGN.json ...]

Default: results/synthetic-campaign.json and results/experimental-campaign.json of this folder
(the --json of `fullspace_calib campaign`). The truth of a run is the `truth: parameters:` its
data file records (what synth made it from). A parameter with no recorded truth of its own is
compared with a stand-in, named in the output: the shared `kx` of experimental-campaign.yaml with
the mean of the three joints' kx (the joints act in parallel in the axial modes).

Prints, as Markdown tables, per parameter:
  1. the campaign's summary (mean, std, rms s.e., ratio, p, verdict) beside the truth's mean and
     std over the same tests;
  2. each run against its own truth: rms and largest relative error, the correlation of calibrated
     with true values over the tests, how many 95 % intervals hold the truth (an interval open on
     a side counts as holding it there) and how many have no finite standard error (the Laplace
     interval is then the parameter's bounds, which hold any truth);
  3. whether the calibrated values vary by unit: the spread of the unit means and the pooled
     spread within units (three assemblies each), and the one-way analysis of variance of the
     log values (F, p). A property drawn per unit (foam G, K) should show between > within and a
     small p; one drawn per assembly (joint kx) should not;
  4. every test's true and calibrated values.
Standard library only.
"""

import json
import math
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", "..", ".."))


# ---- statistics ---------------------------------------------------------------------------------

def mean(v):
    return sum(v) / len(v)


def sd(v):
    m = mean(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else float("nan")


def median(v):
    v = sorted(v)
    if not v:
        return float("nan")
    return v[len(v) // 2] if len(v) % 2 else (v[len(v) // 2 - 1] + v[len(v) // 2]) / 2


def correlation(a, b):
    ma, mb = mean(a), mean(b)
    sab = sum((x - ma) * (y - mb) for x, y in zip(a, b))
    saa = sum((x - ma) ** 2 for x in a)
    sbb = sum((y - mb) ** 2 for y in b)
    return sab / math.sqrt(saa * sbb) if saa > 0 and sbb > 0 else float("nan")


def betacf(a, b, x):
    """Continued fraction of the incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1)
    d = 1 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 300):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1 + num * d
            d = 1 / (d if abs(d) > tiny else tiny)
            c = 1 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1) < 1e-15:
            break
    return h


def betainc(a, b, x):
    """Regularized incomplete beta I_x(a, b)."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    front = math.exp(math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log(1 - x))
    if x < (a + 1) / (a + b + 2):
        return front * betacf(a, b, x) / a
    return 1 - front * betacf(b, a, 1 - x) / b


def f_upper_tail(f, d1, d2):
    """P(F > f) for F with (d1, d2) degrees of freedom."""
    return betainc(d2 / 2, d1 / 2, d2 / (d2 + d1 * f))


def by_unit(units, values):
    """One-way analysis of variance of log(values) grouped by unit."""
    logs = [math.log(v) for v in values]
    groups = {}
    for u, x in zip(units, logs):
        groups.setdefault(u, []).append(x)
    grand = mean(logs)
    k, n = len(groups), len(logs)
    between = sum(len(g) * (mean(g) - grand) ** 2 for g in groups.values()) / (k - 1)
    within = sum((x - mean(g)) ** 2 for g in groups.values() for x in g) / (n - k)
    f = between / within if within > 0 else float("inf")
    # In relative terms: the spread of the unit means and the pooled spread within a unit.
    unit_means = [mean(g) for g in groups.values()]
    return {"between_sd": sd(unit_means), "within_sd": math.sqrt(within), "F": f, "p": f_upper_tail(f, k - 1, n - k)}


# ---- inputs -------------------------------------------------------------------------------------

def find_data(path):
    for candidate in (path, os.path.join(REPO, path), os.path.join(HERE, "data", os.path.basename(path))):
        if os.path.isfile(candidate):
            return candidate
    sys.exit(f"compare-to-truth.py: no data file {path}")


def recorded_truth(data_file):
    """The `truth: parameters:` map of a data file, and the unit and assembly of its name."""
    with open(find_data(data_file)) as f:
        text = f.read()
    block = re.search(r"\n  parameters:\n((?:    .*\n)*)", text)
    truth = {}
    for line in block.group(1).splitlines():
        key, value = line.strip().split(":")
        truth[key.strip().strip('"')] = float(value)
    m = re.search(r"unit-(\d+)-assembly-(\d+)", data_file)
    return truth, int(m.group(1)), int(m.group(2))


def true_value(name, truth):
    """A parameter's truth, or a stand-in with its description."""
    if name in truth:
        return truth[name], ""
    joints = [truth[k] for k in ("joint1_kx", "joint2_kx", "joint3_kx") if k in truth]
    if name == "kx" and len(joints) == 3:
        return mean(joints), "mean of the three joints' kx"
    return None, ""


def g(x, digits=4):
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}g}"


def pct(x):
    return "–" if x is None or math.isnan(x) else f"{100 * x:.1f} %"


# ---- report -------------------------------------------------------------------------------------

def report(path):
    with open(path) as f:
        campaign = json.load(f)
    runs = [r for r in campaign["runs"] if r["ok"]]
    failed = [r for r in campaign["runs"] if not r["ok"]]
    print(f"## {os.path.basename(path)}: {campaign['problem']}\n")
    print(f"{len(runs)} of {len(campaign['runs'])} runs calibrated" +
          "".join(f"; {r['data']} failed: {r.get('reason', '')}" for r in failed) + ".\n")
    truths = [recorded_truth(r["data"]) for r in runs]
    names = [p["name"] for p in campaign["summary"]]
    standins = {}

    print("| parameter | truth mean | truth std | calibrated mean | calibrated std | rms s.e. | ratio | p | verdict |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in campaign["summary"]:
        true = [true_value(s["name"], t[0]) for t in truths]
        if true[0][1]:
            standins[s["name"]] = true[0][1]
        values = [v for v, _ in true if v is not None]
        verdict = "varies between tests" if s["varies_between_tests"] else "spread of the noise"
        if s["homogeneity"]["p_value"] is None:
            verdict = "–"
        print(f"| {s['name']} | {g(mean(values)) if values else '–'} | {g(sd(values), 3) if values else '–'} | "
              f"{g(s['mean'])} | {g(s['standard_deviation'], 3)} | {g(s['rms_standard_error'], 3)} | "
              f"{g(s['spread_ratio'], 3)} | {g(s['homogeneity']['p_value'], 3)} | {verdict} |")
    for name, what in standins.items():
        print(f"\n(truth of `{name}`: the {what})")

    print("\n| parameter | rms rel. error | largest | correlation with truth | 95 % intervals holding the truth | of them without a finite s.e. (the bounds) | median rel. s.e. |")
    print("|---|---|---|---|---|---|---|")
    for j, name in enumerate(names):
        errors, calibrated, true, held, open_, rel_se = [], [], [], 0, 0, []
        for r, (t, _, _) in zip(runs, truths):
            p = r["parameters"][j]
            v, _ = true_value(name, t)
            if v is None:
                continue
            calibrated.append(p["value"])
            true.append(v)
            errors.append(p["value"] / v - 1)
            lo, hi = p["interval"]
            open_ += lo is None or hi is None or p["standard_error"] is None
            held += (lo is None or lo <= v) and (hi is None or v <= hi)
            if p["standard_error"] is not None:
                rel_se.append(p["standard_error"] / p["value"])
        if not errors:
            continue
        rms = math.sqrt(mean([e * e for e in errors]))
        largest = max(errors, key=abs)
        median_se = median(rel_se)
        print(f"| {name} | {pct(rms)} | {100 * largest:+.1f} % | {correlation(calibrated, true):.2f} | "
              f"{held} of {len(errors)} | {open_} | {pct(median_se)} |")

    print("\n| parameter | truth: unit means' std / within-unit std | calibrated: unit means' std / within-unit std | calibrated: F, p (by unit) |")
    print("|---|---|---|---|")
    units = [u for _, u, _ in truths]
    for j, name in enumerate(names):
        true = [true_value(name, t)[0] for t, _, _ in truths]
        calibrated = [r["parameters"][j]["value"] for r in runs]
        a = by_unit(units, true) if None not in true else None
        b = by_unit(units, calibrated)
        truth_text = f"{pct(a['between_sd'])} / {pct(a['within_sd'])}" if a else "–"
        print(f"| {name} | {truth_text} | {pct(b['between_sd'])} / {pct(b['within_sd'])} | "
              f"{b['F']:.3g}, {b['p']:.2g} |")
    print("\n(spreads of the log values, as relative spreads; F tests the unit means of the log values)\n")

    print("| test | " + " | ".join(f"{n}: true / calibrated" for n in names) + " |")
    print("|---|" + "---|" * len(names))
    for r, (t, u, a) in zip(runs, truths):
        cells = []
        for j, name in enumerate(names):
            v, _ = true_value(name, t)
            cells.append(f"{g(v, 4)} / {g(r['parameters'][j]['value'], 4)}")
        print(f"| {u}-{a} | " + " | ".join(cells) + " |")
    print()


def main():
    paths = sys.argv[1:] or [os.path.join(HERE, "results", f) for f in ("synthetic-campaign.json", "experimental-campaign.json")]
    for path in paths:
        if os.path.isfile(path):
            report(path)
        else:
            print(f"(no {path})\n")


if __name__ == "__main__":
    main()
