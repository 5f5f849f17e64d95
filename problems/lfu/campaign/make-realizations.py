#!/usr/bin/env python3
"""Writes the campaign example's 18 synthetic tests: 6 LFU units, each assembled 3 times.

For every test (unit U = 1..6, assembly A = 1..3) it writes

  truth/unit-U-assembly-A.yaml       the truth model: ../lfu.yaml with this unit's foam moduli and
                                     this assembly's three joint stiffnesses;
  data/unit-U-assembly-A.yaml        `fullspace_calib synth` on synthetic-campaign.yaml with that
                                     truth: the ten lowest modes with shapes at the 24 sensor DOFs,
                                     with measurement noise (seed 100 U + A);
  data-axial/unit-U-assembly-A.yaml  the same test's two axial frequencies alone (the values of
                                     data/..., not new draws), as the report's experimental data:
                                     what experimental-campaign.yaml reads. Each is paired with the
                                     model mode of its number in the test (5 or 6, and 9), not by
                                     family: see axial_data.

The distribution (log-normal, around the values of ../synthetic.yaml's truth):

  foam G, foam K   vary from unit to unit, the same for the three assemblies of a unit (the foam
                   is bonded in a unit once): G = 1.585e4 psi * exp(0.12 Z), K = 4.134e4 psi *
                   exp(0.12 Z'), Z, Z' independent standard normal per unit; one modulus for the
                   five pads of a unit;
  joint kx         varies with every assembly (the joints are remade on each reassembly), each
                   joint on its own: kx = 2.46e6 lbf/in * exp(0.25 Z), Z independent per joint
                   and per assembly.

Drawn values are rounded to 4 significant digits; the rounded values are the truth. Draws come
from Python's `random.Random(2015)` (Mersenne Twister, the same on every platform), in the order:
for each unit, its G then its K draw, then for each of its assemblies joint 1, 2, 3.

Measurement noise (synth): 0.2 % standard deviation on each frequency, 2 % of a shape's largest
value on each shape value.

Usage (from anywhere; takes about 25 s):
    python3 problems/lfu/campaign/make-realizations.py [--tool build/bin/fullspace_calib]
The tool defaults to $FULLSPACE_CALIB, else build/bin/fullspace_calib of this repository.
Standard library only.
"""

import argparse
import json
import math
import os
import random
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", "..", ".."))

SEED = 2015
UNITS = 6
ASSEMBLIES = 3
KX0, G0, K0 = 2.46e6, 1.585e4, 4.134e4  # ../synthetic.yaml's truth: joint kx, foam G, foam K
SIGMA_FOAM = 0.12  # log-normal sigma of foam G and K, per unit
SIGMA_JOINT = 0.25  # log-normal sigma of each joint's kx, per assembly
NOISE_FREQ = 0.002  # relative standard deviation of a frequency
NOISE_SHAPE = 0.02  # standard deviation of a shape value, relative to the shape's largest
MODES = "1,2,3,4,5,6,7,8,9,10"  # the truth model's modes each test measures

# lfu.yaml's blocks other than the foam, repeated here because a truth file's `blocks:` replaces
# the whole section; checked against lfu.yaml below, so that the truth differs only in G, K, kx.
RIGID_BLOCKS = [
    "post:  {E: 3.0e7, nu: 0.29, density: 7.3e-4}",
    "base:  {E: 5.0e7, nu: 0.28, density: 1.55e-3}",
    "top:   {E: 3.0e7, nu: 0.29, density: 7.33e-4}",
]
FOAM_DENSITY = "3.0e-5"
JOINT_NODES = [("j1a", "j1b"), ("j2a", "j2b"), ("j3a", "j3b")]
JOINT_KYZ = "ky: 2.0e8, kz: 2.0e8"


def rounded(x):
    return float(f"{x:.4g}")


def draw():
    """The truth of every test: {(unit, assembly): {"G", "K", "kx": [3]}}."""
    rng = random.Random(SEED)
    truths = {}
    for u in range(1, UNITS + 1):
        g = rounded(G0 * math.exp(SIGMA_FOAM * rng.gauss(0.0, 1.0)))
        k = rounded(K0 * math.exp(SIGMA_FOAM * rng.gauss(0.0, 1.0)))
        for a in range(1, ASSEMBLIES + 1):
            kx = [rounded(KX0 * math.exp(SIGMA_JOINT * rng.gauss(0.0, 1.0))) for _ in range(3)]
            truths[(u, a)] = {"G": g, "K": k, "kx": kx}
    return truths


def check_against_lfu():
    """The lines this script repeats from lfu.yaml must still be there, as written."""
    with open(os.path.join(HERE, "..", "lfu.yaml")) as f:
        lfu = re.sub(r"[ \t]+", " ", f.read())
    expected = [s for s in RIGID_BLOCKS]
    expected += [f"foam{i}: {{K: 4.134e4, G: 1.585e4, density: {FOAM_DENSITY}}}" for i in range(1, 6)]
    expected += [f"joint{j + 1}: {{nodes: [{a}, {b}], kx: 2.46e6, {JOINT_KYZ}}}" for j, (a, b) in enumerate(JOINT_NODES)]
    for line in expected:
        if re.sub(r"[ \t]+", " ", line) not in lfu:
            sys.exit(f"make-realizations.py: ../lfu.yaml no longer holds '{line}'; update this script")


def name(u, a):
    return f"unit-{u}-assembly-{a}.yaml"


def truth_file(u, a, t):
    lines = [
        f"# Truth of LFU unit {u}, assembly {a}, for the campaign example (written by make-realizations.py,",
        f"# seed {SEED}; do not edit). The model of ../../lfu.yaml with unit {u}'s foam moduli (all five pads)",
        f"# and assembly {a}'s joint stiffnesses kx; every other property is lfu.yaml's.",
        "extends: ../../lfu.yaml",
        f"name: lfu-unit-{u}-assembly-{a}",
        f"description: LFU truth of unit {u} (foam G {t['G']:.4g}, K {t['K']:.4g}), assembly {a} (joint kx)",
        "",
        "blocks:",
    ]
    lines += [f"  {b}" for b in RIGID_BLOCKS]
    lines += [f"  foam{i}: {{K: {t['K']:.4g}, G: {t['G']:.4g}, density: {FOAM_DENSITY}}}" for i in range(1, 6)]
    lines += ["", "joints:"]
    lines += [
        f"  joint{j + 1}: {{nodes: [{na}, {nb}], kx: {t['kx'][j]:.4g}, {JOINT_KYZ}}}"
        for j, (na, nb) in enumerate(JOINT_NODES)
    ]
    return "\n".join(lines) + "\n"


def axial_modes(tool, u, a):
    """The truth model's two modes whose motion is most axial (largest share of the parts'
    translation along x), in frequency order: what a test engineer calls the axial modes. With
    unequal joints the first axial mode couples with the lateral mode next to it (1277 Hz at the
    nominal values), and its axial share may fall below the 0.5 for which `modes` labels a mode
    `axial`, so the label alone does not find it in every test."""
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "modes.json")
        run([tool, "modes", f"truth/{name(u, a)}", "--json", out])
        with open(out) as f:
            modes = json.load(f)["modes"]
    ranked = sorted(modes, key=lambda m: -m["part_translation_fraction"][0])[:2]
    return sorted((m["index"], m["part_translation_fraction"][0]) for m in ranked)


def axial_data(u, a, synthesized, axial_modes):
    """The axial modes of a synth data file, as a frequency-only data file.

    Each is paired with the model mode of the same number as in the test (`pair: {model_mode:
    n}`, as synth pairs frequency-only data), not by family (`{family: axial, index: i}`, as
    ../experimental.yaml): the model's first axial mode veers with the lateral mode next to it,
    both near half axial, and where a calibration step moves the axial share across the 0.5 of
    the family label, the pairing jumps to the other mode and the misfit with it; the line search
    then stops short of the fit (README.md). The mode's number is known from the test, which
    measured the ten lowest modes."""
    blocks = re.split(r"\n(?=  - label: )", synthesized.split("\nmodes:\n", 1)[1])
    by_mode = {}
    for block in blocks:
        freq = re.search(r"frequency_hz: (\S+)", block).group(1)
        mode = int(re.search(r"truth_mode: (\S+)", block).group(1))
        truth_hz = re.search(r"truth_frequency_hz: (\S+)", block).group(1)
        by_mode[mode] = (freq, truth_hz)
    truth = re.search(r"\ntruth:.*?\n(?=modes:)", synthesized, re.S).group(0).strip("\n")
    # synth compared the truth with synthetic-campaign.yaml's model, whose joints are calibrated
    # one by one; experimental-campaign.yaml's single kx cannot make three unequal joints.
    truth = truth.replace("# none: the nominal model form is right",
                          "# none for synthetic-campaign.yaml; a shared kx cannot make three unequal joints")
    seed = re.search(r"\n  seed: (\d+)", synthesized).group(1)
    out = [
        f"# The two axial frequencies of data/{name(u, a)} (the same noisy values; written by",
        "# make-realizations.py), without shapes, each paired with the model mode of its number in the",
        "# test: the report's experimental data, for one test.",
        'synthesized_from: "synthetic-campaign.yaml"',
        f"noise: {{frequency: {NOISE_FREQ}, seed: {seed}}}",
        truth,
        "modes:",
    ]
    for i, (mode, share) in enumerate(axial_modes, 1):
        freq, truth_hz = by_mode[mode]
        out += [
            f'  - label: "axial {i}"   # the truth\'s mode {mode}: {share:.0%} of its parts\' translation is axial',
            f"    frequency_hz: {freq}",
            f"    truth_mode: {mode}",
            f"    truth_frequency_hz: {truth_hz}",
            f"    pair: {{model_mode: {mode}}}",
        ]
    return "\n".join(out) + "\n"


def run(command):
    """Runs the tool from this folder, so that the files it writes record relative paths."""
    # One BLAS thread: the eigenvectors' last digits depend on the thread count (about 1e-13).
    env = dict(os.environ)
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    result = subprocess.run(command, cwd=HERE, env=env, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"make-realizations.py: {' '.join(command)} failed ({result.returncode}):\n{result.stdout}{result.stderr}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    default_tool = os.environ.get("FULLSPACE_CALIB", os.path.join(REPO, "build", "bin", "fullspace_calib"))
    parser.add_argument("--tool", default=default_tool, help="the fullspace_calib executable (default %(default)s)")
    args = parser.parse_args()
    tool = os.path.abspath(args.tool)
    check_against_lfu()
    truths = draw()
    for folder in ("truth", "data", "data-axial"):
        os.makedirs(os.path.join(HERE, folder), exist_ok=True)

    print(f"{'test':<20} {'foam G':>9} {'foam K':>9} {'joint1 kx':>10} {'joint2 kx':>10} {'joint3 kx':>10}   "
          "axial modes (axial share)")
    for (u, a), t in truths.items():
        with open(os.path.join(HERE, "truth", name(u, a)), "w") as f:
            f.write(truth_file(u, a, t))
        run([tool, "synth", "synthetic-campaign.yaml", "--truth", f"truth/{name(u, a)}", "--modes", MODES,
             "--noise-freq", str(NOISE_FREQ), "--noise-shape", str(NOISE_SHAPE), "--seed", str(100 * u + a),
             "-o", f"data/{name(u, a)}"])
        axial = axial_modes(tool, u, a)
        with open(os.path.join(HERE, "data", name(u, a))) as f:
            synthesized = f.read()
        with open(os.path.join(HERE, "data-axial", name(u, a)), "w") as f:
            f.write(axial_data(u, a, synthesized, axial))
        kx = " ".join(f"{v:10.4g}" for v in t["kx"])
        shares = "  ".join(f"{m} ({share:.2f})" for m, share in axial)
        print(f"unit {u} assembly {a}     {t['G']:9.4g} {t['K']:9.4g} {kx}   {shares}", flush=True)

    def stats(values):
        mean = sum(values) / len(values)
        sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
        return mean, sd

    print("\nover the 18 tests (mean, standard deviation, ratio):")
    columns = {"foam G": [t["G"] for t in truths.values()], "foam K": [t["K"] for t in truths.values()]}
    for j in range(3):
        columns[f"joint{j + 1} kx"] = [t["kx"][j] for t in truths.values()]
    for label, values in columns.items():
        mean, sd = stats(values)
        print(f"  {label:<10} {mean:10.4g} {sd:10.3g} {sd / mean:7.1%}")


if __name__ == "__main__":
    main()
