#!/usr/bin/env python3
"""SciPy baseline for bench_identify (issue 3): the same fit written the way an engineer would in
SciPy -- scipy.optimize.least_squares (trf, bounds, 2-point Jacobian) over solve_ivp (LSODA) of
the drive-line model of bench/driveline/scipy_simulate.py. Same record, window, free parameters,
bounds and start (the scene's nominal values) as the bundled fit config; gain and offset per
channel fitted too. No continuation, no scan: a single local fit. Run twice: from the nominal
start, and from the truth (SciPy's easiest case, for a speed ratio at the accuracy MillKit
reaches from the nominal start).

usage: scipy_identify.py SCENE.toml RECORD.csv
Prints: wall time, function evaluations, and each parameter's error against the truth of
datasets/records/mill5_two_spindles.spec.toml.
"""
import os
import sys
import time
import tomllib

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "driveline"))
import scipy_simulate as sim  # noqa: E402

ROOT = os.path.join(HERE, "..", "..")


def main():
    base = sim.load(sys.argv[1])
    record = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
    with open(os.path.join(ROOT, "datasets/records/mill5_two_spindles.fit.toml"), "rb") as f:
        fit = tomllib.load(f)
    with open(os.path.join(ROOT, "datasets/records/mill5_two_spindles.spec.toml"), "rb") as f:
        truth = tomllib.load(f)["truth"]
    lo_t, hi_t = fit["fit"]["window"]
    rows = (record[:, 0] >= lo_t) & (record[:, 0] <= hi_t)
    t_eval = record[rows, 0]
    y = record[rows, 1:3]
    names = [p["name"] for p in fit["free"]]
    lower = np.array([p["lower"] for p in fit["free"]])
    upper = np.array([p["upper"] for p in fit["free"]])
    link_index = {l["name"]: i for i, l in enumerate(base["links"])}

    def nominal(name):
        if name == "bite_time":
            return min(s["start"] for s in base["sources"])
        link, prop = name.rsplit(".", 1)
        key = {"damping": "d", "backlash": "bl", "stiffness": "c"}[prop]
        return base["links"][link_index[link]][key]

    start = np.array([nominal(n) for n in names])
    channels = [link_index["upper_spindle"], link_index["lower_spindle"]]
    scale = np.abs(y).max(axis=0)
    nfev = [0]

    def model_with(p):
        model = {**base, "links": [dict(l) for l in base["links"]],
                 "sources": [dict(s) for s in base["sources"]]}
        for name, value in zip(names, p):
            if name == "bite_time":
                shift = value - min(s["start"] for s in base["sources"])
                for s in model["sources"]:
                    s["start"] += shift
                continue
            link, prop = name.rsplit(".", 1)
            key = {"damping": "d", "backlash": "bl", "stiffness": "c"}[prop]
            model["links"][link_index[link]][key] = value
        return model

    def simulate(p):
        model = model_with(p)
        L = len(model["links"])
        J = model["J"]

        def rhs(t, s):
            psi, w = s[:L], s[L:]
            acc = sim.source_torques(model, t)
            dpsi = np.empty(L)
            for k, l in enumerate(model["links"]):
                v = w[l["a"]] - w[l["b"]]
                dpsi[k] = v
                m = sim.law(model["law"], l["c"], l["d"], l["bl"], psi[k], v)
                acc[l["a"]] -= m
                acc[l["b"]] += m
            return np.concatenate([dpsi, acc / J])

        s0 = sim.initial_state(model)
        atol = np.concatenate([[max(0.5 * l["bl"], 1e-6) * 1e-6 for l in model["links"]],
                               np.full(len(J), 1e-6 * max(model["speed"], 1.0))])
        sol = solve_ivp(rhs, (0.0, t_eval[-1]), s0, method="LSODA", t_eval=t_eval, rtol=1e-6,
                        atol=atol)
        out = np.empty((len(t_eval), 2))
        for j, k in enumerate(channels):
            l = model["links"][k]
            for i in range(len(t_eval)):
                v = sol.y[L + l["a"], i] - sol.y[L + l["b"], i]
                out[i, j] = sim.law(model["law"], l["c"], l["d"], l["bl"], sol.y[k, i], v)
        return out

    def residual(x):
        nfev[0] += 1
        p = lower + x[:len(names)] * (upper - lower)
        m = simulate(p)
        g = x[len(names)::2]
        o = x[len(names) + 1::2] * scale
        return ((g * m + o - y) / scale).ravel()

    def run(label, p0):
        nfev[0] = 0
        x0 = np.concatenate([(p0 - lower) / (upper - lower), [1.0, 0.0, 1.0, 0.0]])
        lb = np.concatenate([np.zeros(len(names)), [0.5, -1.0, 0.5, -1.0]])
        ub = np.concatenate([np.ones(len(names)), [2.0, 1.0, 2.0, 1.0]])
        began = time.perf_counter()
        result = least_squares(residual, x0, bounds=(lb, ub), method="trf", diff_step=1e-3,
                               max_nfev=60)
        wall = time.perf_counter() - began
        p = lower + result.x[:len(names)] * (upper - lower)
        print(f"SciPy from {label}: {wall:.1f} s wall, {nfev[0]} simulations, status "
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

    run("the nominal start", start)
    # The easiest case for SciPy: started at the truth, it only has to settle into the minimum
    # of this record, which MillKit reaches from the nominal start.
    run("the truth", np.array([truth[n] for n in names]))

if __name__ == "__main__":
    main()
