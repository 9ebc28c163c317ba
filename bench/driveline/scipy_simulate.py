#!/usr/bin/env python3
"""SciPy baseline for bench_simulate (issue 2): the same drive-line model (SPEC §2) written the
way an engineer would in SciPy -- solve_ivp over the non-smooth right-hand side, no event
handling -- timed at several rtol and compared with MillKit's reference torques.

usage: scipy_simulate.py SCENE.toml REFERENCE.csv
Supports masses, links (limited / no_pull / linear), ramp torque sources; no drive, no band,
no gear ratio.
Prints markdown table rows: | SciPy METHOD | rtol | - | rhs calls | wall ms | max error / peak |
"""
import sys
import time
import tomllib

import numpy as np
from scipy.integrate import solve_ivp


def load(path):
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    if "drive" in doc:
        raise SystemExit("scipy_simulate.py: scenes with a drive are not supported")
    masses = [m["name"] for m in doc["mass"]]
    J = np.array([m["inertia"] for m in doc["mass"]], float)
    links = []
    for l in doc["link"]:
        if float(l.get("ratio", 1.0)) != 1.0:
            raise SystemExit("scipy_simulate.py: links with a gear ratio are not supported")
        links.append(dict(name=l["name"], a=masses.index(l["between"][0]),
                          b=masses.index(l["between"][1]), c=float(l["stiffness"]),
                          d=float(l.get("damping", 0.0)), bl=float(l.get("backlash", 0.0)),
                          gp=float(l.get("gap_position", -1.0))))
    sources = []
    for t in doc.get("torque", []):
        sources.append(dict(m=masses.index(t["at"]), before=float(t.get("before", 0.0)),
                            after=float(t["after"]), start=float(t.get("start", 0.0)),
                            rise=float(t.get("rise", 0.0))))
    sc = doc["scene"]
    return dict(J=J, links=links, sources=sources, law=sc.get("contact", "limited"),
                duration=float(sc["duration"]), rate=float(sc["sample_rate"]),
                speed=float(doc.get("initial", {}).get("speed", 0.0)), masses=masses)


def source_torques(model, t):
    M = np.zeros(len(model["J"]))
    for s in model["sources"]:
        if t < s["start"]:
            v = s["before"]
        elif s["rise"] <= 0 or t >= s["start"] + s["rise"]:
            v = s["after"]
        else:
            v = s["before"] + (s["after"] - s["before"]) * (t - s["start"]) / s["rise"]
        M[s["m"]] += v
    return M


def law(kind, c, d, b, psi, v):
    if b == 0.0:  # SPEC §2.2: a link without clearance is a plain spring-damper
        return c * psi + d * v
    h = 0.5 * b
    if psi > h:
        tc, td = c * (psi - h), d * v
        if kind == "linear":
            return tc + td
        if kind == "no_pull":
            return max(tc + td, 0.0)
        return 0.0 if tc + td <= 0 else tc + min(tc, td)
    if psi < -h:
        tc, td = c * (psi + h), d * v
        if kind == "linear":
            return tc + td
        if kind == "no_pull":
            return min(tc + td, 0.0)
        return 0.0 if tc + td >= 0 else tc + max(tc, td)
    return 0.0


def subtree(model, k):
    """Masses on the `to` side of link k."""
    n = len(model["J"])
    adj = [[] for _ in range(n)]
    for i, l in enumerate(model["links"]):
        if i != k:
            adj[l["a"]].append(l["b"])
            adj[l["b"]].append(l["a"])
    seen, stack = {model["links"][k]["b"]}, [model["links"][k]["b"]]
    while stack:
        i = stack.pop()
        for j in adj[i]:
            if j not in seen:
                seen.add(j)
                stack.append(j)
    return sorted(seen)


def initial_state(model):
    M = source_torques(model, 0.0)
    eps = M.sum() / model["J"].sum()
    psi = []
    scale = np.abs(M).sum()
    for k, l in enumerate(model["links"]):
        B = subtree(model, k)
        m = model["J"][B].sum() * eps - M[B].sum()
        if abs(m) <= 1e-12 * scale:
            psi.append(l["gp"] * 0.5 * l["bl"])
        else:
            psi.append(np.sign(m) * 0.5 * l["bl"] + m / l["c"])
    return np.concatenate([psi, np.full(len(model["J"]), model["speed"])])


def main():
    model = load(sys.argv[1])
    ref = np.loadtxt(sys.argv[2], delimiter=",", skiprows=1)
    L = len(model["links"])
    J = model["J"]
    calls = [0]

    def rhs(t, y):
        calls[0] += 1
        psi, w = y[:L], y[L:]
        acc = source_torques(model, t)
        dpsi = np.empty(L)
        for k, l in enumerate(model["links"]):
            v = w[l["a"]] - w[l["b"]]
            dpsi[k] = v
            m = law(model["law"], l["c"], l["d"], l["bl"], psi[k], v)
            acc[l["a"]] -= m
            acc[l["b"]] += m
        return np.concatenate([dpsi, acc / J])

    def torques(y):
        out = np.empty((y.shape[1], L))
        for k, l in enumerate(model["links"]):
            for i in range(y.shape[1]):
                v = y[L + l["a"], i] - y[L + l["b"], i]
                out[i, k] = law(model["law"], l["c"], l["d"], l["bl"], y[k, i], v)
        return out

    y0 = initial_state(model)
    t_eval = ref[:, 0]
    peak = np.abs(ref[:, 1:]).max()
    scale = np.concatenate([[max(0.5 * l["bl"] + 1e-6, 1e-6) for l in model["links"]],
                            np.full(len(J), max(abs(model["speed"]), 1.0))])
    for method, rtols in (("DOP853", (1e-6, 1e-8, 1e-10, 1e-12)), ("LSODA", (1e-6, 1e-8, 1e-10))):
        for rtol in rtols:
            calls[0] = 0
            start = time.perf_counter()
            sol = solve_ivp(rhs, (0.0, t_eval[-1]), y0, method=method, t_eval=t_eval, rtol=rtol,
                            atol=rtol * scale)
            wall = time.perf_counter() - start
            if not sol.success:
                print(f"| SciPy {method} | rtol {rtol:.0e} | - | {calls[0]} | {wall*1e3:.1f} | "
                      f"failed: {sol.message} |")
                continue
            err = np.abs(torques(sol.y) - ref[:, 1:]).max() / peak
            print(f"| SciPy {method} | rtol {rtol:.0e} | - | {calls[0]} rhs | {wall*1e3:.1f} | "
                  f"{err:.1e} |", flush=True)


if __name__ == "__main__":
    main()
