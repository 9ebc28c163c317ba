#!/usr/bin/env python3
"""SciPy baseline of a fit (issues 3 and 15): the fit written the way an engineer would in SciPy
-- scipy.optimize.least_squares (trf, bounds, 2-point Jacobian) over solve_ivp (LSODA) of the
drive-line model of bench/driveline/scipy_simulate.py, a gain and an offset per channel fitted
too. No continuation, no scan: a single local fit. No recorder filter.

As a program it fits one case that bench_random_lines wrote (a JSON file: the model in
scipy_simulate's form, the record's window, the channels' links, the free parameters with bounds,
start, truth and MillKit's standard error), once from the start and once from the truth, and
prints a line per fit:
    SCIPY <from> <wall s> <simulations> <status> <worst |z|> <parameter>
z = (SciPy's value - truth) / MillKit's standard error.

usage: scipy_fit.py CASE.json
"""
import json
import os
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "driveline"))
import scipy_simulate as sim  # noqa: E402

KEYS = {"damping": "d", "backlash": "bl", "stiffness": "c", "gap_position": "gp"}


def with_values(base, names, link_index, p):
    """The model with the free parameters set (bite_time moves every source's start)."""
    model = {**base, "links": [dict(l) for l in base["links"]],
             "sources": [dict(s) for s in base["sources"]]}
    for name, value in zip(names, p):
        if name == "bite_time":
            shift = value - min(s["start"] for s in base["sources"])
            for s in model["sources"]:
                s["start"] += shift
            continue
        link, prop = name.rsplit(".", 1)
        model["links"][link_index[link]][KEYS[prop]] = value
    return model


def nominal(base, link_index, name):
    if name == "bite_time":
        return min(s["start"] for s in base["sources"])
    link, prop = name.rsplit(".", 1)
    return base["links"][link_index[link]][KEYS[prop]]


class Fit:
    """least_squares over solve_ivp of `base` against y (samples x channels) at t_eval; each
    channel is the torque of the link channels[j]."""

    def __init__(self, base, t_eval, y, channels, names, lower, upper):
        self.base, self.t_eval, self.y, self.channels = base, t_eval, y, channels
        self.names, self.lower, self.upper = names, lower, upper
        self.link_index = {l["name"]: i for i, l in enumerate(base["links"])}
        self.scale = np.abs(y).max(axis=0)
        self.nfev = 0

    def simulate(self, p):
        model = with_values(self.base, self.names, self.link_index, p)
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
        sol = solve_ivp(rhs, (0.0, self.t_eval[-1]), s0, method="LSODA", t_eval=self.t_eval,
                        rtol=1e-6, atol=atol)
        out = np.zeros((len(self.t_eval), len(self.channels)))
        if not sol.success or sol.y.shape[1] != len(self.t_eval):
            return out + 1e30  # a run that fails is a very bad fit, as in an engineer's script
        for j, k in enumerate(self.channels):
            l = model["links"][k]
            for i in range(len(self.t_eval)):
                v = sol.y[L + l["a"], i] - sol.y[L + l["b"], i]
                out[i, j] = sim.law(model["law"], l["c"], l["d"], l["bl"], sol.y[k, i], v)
        return out

    def residual(self, x):
        self.nfev += 1
        n = len(self.names)
        p = self.lower + x[:n] * (self.upper - self.lower)
        m = self.simulate(p)
        g = x[n::2]
        o = x[n + 1::2] * self.scale
        return ((g * m + o - self.y) / self.scale).ravel()

    def run(self, p0):
        """Returns (values, wall s, simulations, least_squares result)."""
        self.nfev = 0
        c = len(self.channels)
        x0 = np.concatenate([(p0 - self.lower) / (self.upper - self.lower), [1.0, 0.0] * c])
        lb = np.concatenate([np.zeros(len(self.names)), [0.5, -1.0] * c])
        ub = np.concatenate([np.ones(len(self.names)), [2.0, 1.0] * c])
        began = time.perf_counter()
        result = least_squares(self.residual, x0, bounds=(lb, ub), method="trf", diff_step=1e-3,
                               max_nfev=60)
        wall = time.perf_counter() - began
        p = self.lower + result.x[:len(self.names)] * (self.upper - self.lower)
        return p, wall, self.nfev, result


def main():
    with open(sys.argv[1]) as f:
        case = json.load(f)
    base = dict(case["model"])
    base["J"] = np.array(base["J"], float)
    free = case["free"]
    names = [p["name"] for p in free]
    fit = Fit(base, np.array(case["t"], float), np.array(case["y"], float).T, case["channels"],
              names, np.array([p["lower"] for p in free]), np.array([p["upper"] for p in free]))
    truth = np.array([p["truth"] for p in free])
    # A parameter MillKit calls not identifiable has no standard error: it is not scored.
    se = np.array([p["se"] if p.get("se") else np.inf for p in free])
    for label, p0 in (("start", np.array([p["start"] for p in free])), ("truth", truth)):
        p, wall, nfev, result = fit.run(p0)
        z = np.abs(p - truth) / se
        worst = int(np.argmax(z))
        print(f"SCIPY {label} {wall:.3f} {nfev} {result.status} {z[worst]:.3g} {names[worst]}",
              flush=True)


if __name__ == "__main__":
    main()
