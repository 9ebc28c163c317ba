#!/usr/bin/env python3
"""SciPy baseline for bench_identify (issue 3): the fit of scipy_fit.py on the bundled record,
with the same window, free parameters, bounds and start (the scene's nominal values) as the
bundled fit config. Run twice: from the nominal start, and from the truth (SciPy's easiest case,
for a speed ratio at the accuracy MillKit reaches from the nominal start).

usage: scipy_identify.py SCENE.toml RECORD.csv
Prints: wall time, function evaluations, and each parameter's error against the truth of
datasets/records/mill5_two_spindles.spec.toml; and per start a line `SCIPY_RESULT <start> <wall s>
<simulations> <value>...` (the values in the fit config's order), which bench_identify reads.
"""
import os
import sys
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "driveline"))
import scipy_fit  # noqa: E402
import scipy_simulate as sim  # noqa: E402

ROOT = os.path.join(HERE, "..", "..")


def main():
    base = sim.load(sys.argv[1])
    record = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
    with open(os.path.join(ROOT, "datasets/records/mill5_two_spindles.fit.toml"), "rb") as f:
        config = tomllib.load(f)
    with open(os.path.join(ROOT, "datasets/records/mill5_two_spindles.spec.toml"), "rb") as f:
        truth = tomllib.load(f)["truth"]
    # The bundled config fits the whole record unless it names a window (MillKit's default).
    lo_t, hi_t = config["fit"].get("window", [record[0, 0], record[-1, 0]])
    rows = (record[:, 0] >= lo_t) & (record[:, 0] <= hi_t)
    names = [p["name"] for p in config["free"]]
    link_index = {l["name"]: i for i, l in enumerate(base["links"])}
    fit = scipy_fit.Fit(base, record[rows, 0], record[rows, 1:3],
                        [link_index["upper_spindle"], link_index["lower_spindle"]], names,
                        np.array([p["lower"] for p in config["free"]]),
                        np.array([p["upper"] for p in config["free"]]))

    def run(key, label, p0):
        p, wall, nfev, result = fit.run(p0)
        print(f"SciPy from {label}: {wall:.1f} s wall, {nfev} simulations, status "
              f"{result.status} ({result.message})\n")
        print("| parameter | truth | SciPy | relative error |\n|---|---|---|---|")
        worst = 0.0
        for name, value in zip(names, p):
            true = truth[name]
            rel = abs(value - true) / abs(true)
            worst = max(worst, rel)
            print(f"| {name} | {true:.6g} | {value:.6g} | {rel:.2e} |")
        print(f"\nSciPy from {label}: worst relative parameter error {worst:.2e}; "
              f"wall {wall:.1f} s\n", flush=True)
        # For bench_identify: the start's label, wall s, simulations, every value at full precision.
        print(f"SCIPY_RESULT {key} {wall!r} {nfev} " + " ".join(repr(float(v)) for v in p),
              flush=True)

    run("nominal", "the nominal start",
        np.array([scipy_fit.nominal(base, link_index, n) for n in names]))
    # The easiest case for SciPy: started at the truth, it only has to settle into the minimum
    # of this record, which MillKit reaches from the nominal start.
    run("truth", "the truth", np.array([truth[n] for n in names]))


if __name__ == "__main__":
    main()
