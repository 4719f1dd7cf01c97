"""PyMUST (SIMUS) channel data for a phased (P4-2v) and a convex (C5-2v) array,
diverging and focused transmits, with PyMUST's own delay-and-sum images on its
polar grid as the reference usray's beamformer is checked against
(`crates/usray-signal/tests/pymust_probes.rs`).

Run with the peers venv (pymust 0.1.9, numpy, scipy):

    /tmp/peersvenv/bin/python tests/python/pymust_probes.py crates/usray-signal/tests/data/probes

Writes, per case NAME (p4_diverging, p4_focused, c5_diverging, c5_focused):
  NAME.npy / NAME.json                 usray-channels/1, float32 [n_tx, n_el, n_samples]
  NAME_bmode_pymust.npy / .json        PyMUST's dB image, float32 [n_r, n_theta], 0 dB max

Clock (CONTRACT §1 as extended for these transmits): usray's t = 0 is the
instant the transmitted wavefront passes the probe-frame origin (0, 0); element
e fires at tau_e = (|e - v| - |v|)/c for a virtual source v behind the array and
tau_e = (|f| - |f - e|)/c for a focus f in front of it. PyMUST's delays are
tau_e - min(tau) (first element fires at 0) and SIMUS's sample 0 is that
instant, so in usray's clock sample 0 is at t0_s = min_e tau_e. The script
checks that PyMUST's delays equal tau_e - min(tau) to 1e-12 s.
"""

import copy
import json
import os
import sys
import time

import numpy as np
import pymust

C = 1540.0
SEED = 2024


def positions(param):
    xe, ze, the, h = param.getElementPositions()
    return xe.ravel(), ze.ravel(), the.ravel(), float(np.ravel(h)[0])


def usray_delays(param, kind, point):
    """tau_e on usray's clock (see the module doc), seconds."""
    xe, ze, _, _ = positions(param)
    px, pz = point
    d = np.hypot(xe - px, ze - pz)
    if kind == "diverging":
        return (d - np.hypot(px, pz)) / C
    return (np.hypot(px, pz) - d) / C


def scatterers(points_mm, disk, rng):
    """Point targets (rc 1) plus a disk of speckle (rc 0.1, uniform density)."""
    (cx, cz, r, per_mm2) = disk
    n = int(round(np.pi * r * r * per_mm2))
    rr = r * np.sqrt(rng.uniform(0, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    xs = np.concatenate([np.array([p[0] for p in points_mm]), cx + rr * np.cos(th)]) * 1e-3
    zs = np.concatenate([np.array([p[1] for p in points_mm]), cz + rr * np.sin(th)]) * 1e-3
    rc = np.concatenate([np.ones(len(points_mm)), 0.1 * np.ones(n)])
    return xs, zs, rc


def simulate(param, dels, xs, zs, rc):
    opt = pymust.utils.Options()
    opt.ParPool = False
    rf, _ = pymust.simus(xs, zs, rc, dels, param, opt)
    return rf  # [n_t, n_el]


def polar_grid(param, n_r, n_theta, zmax, width):
    """PyMUST's impolgrid (x, z) [n_r, n_theta], with the (r, theta) axes."""
    if np.isinf(param.radius):
        x, z = pymust.impolgrid(np.array([n_r, n_theta]), zmax, width, param)
        origin_z = 0.0
    else:
        x, z = pymust.impolgrid(np.array([n_r, n_theta]), zmax, param)
        _, _, _, h = positions(param)
        origin_z = -h
    r = np.hypot(x[:, 0], z[:, 0] - origin_z)
    theta = np.arctan2(x[0, :], z[0, :] - origin_z)
    return x, z, r, theta, origin_z


def case(name, param, probe_kind, tx, pts, disk, grid, fnumber, out, rng):
    """tx: list of (kind, (x, z) m, pymust delays)."""
    xs, zs, rc = scatterers(pts, disk, rng)
    fs = param.fs
    xe, ze, _, _ = positions(param)
    rfs, t0s = [], []
    for kind, point, dels in tx:
        tau = usray_delays(param, kind, point)
        err = np.max(np.abs((tau - tau.min()) - dels.ravel()))
        assert err < 1e-12, f"{name}: PyMUST delays differ from usray's by {err} s"
        t0s.append(float(tau.min()))
        t = time.time()
        cache = os.environ.get("PYMUST_PROBES_CACHE")  # reuse SIMUS runs while iterating
        hit = cache and os.path.join(cache, f"{name}_{len(rfs)}.npy")
        if hit and os.path.exists(hit):
            rfs.append(np.load(hit))
        else:
            rfs.append(simulate(param, dels, xs, zs, rc))
            if hit:
                os.makedirs(cache, exist_ok=True)
                np.save(hit, rfs[-1])
        print(f"{name} {kind} {point}: SIMUS {rfs[-1].shape} in {time.time() - t:.0f} s", flush=True)
    # Record length: the latest echo (any element firing, any scatterer, any
    # receiver) + 3 µs of pulse, on the longest transmit's clock.
    d_rx = np.hypot(xe[None, :] - xs[:, None], ze[None, :] - zs[:, None])
    latest = 0.0
    for _, _, dels in tx:
        latest = max(latest, np.max(dels.ravel()[None, :] + d_rx / C) + np.max(d_rx) / C)
    ns = int(np.ceil((latest + 3e-6) * fs))
    data = np.zeros((len(tx), param.Nelements, ns), np.float32)
    dropped = []
    for i, rf in enumerate(rfs):
        n = min(ns, rf.shape[0])
        data[i, :, :n] = rf[:n].T
        dropped.append(float(np.sum(rf[n:] ** 2) / np.sum(rf ** 2)))
    np.save(os.path.join(out, name + ".npy"), data)

    probe = {
        "kind": probe_kind,
        "n_elements": int(param.Nelements),
        "pitch_m": float(param.pitch),
        "element_width_m": float(param.width),
        "bandwidth_percent": float(param.bandwidth),
    }
    if probe_kind == "convex":
        probe["radius_m"] = float(param.radius)
    key = {"diverging": "virtual_source_m", "focused": "focus_m"}
    meta = {
        "format": "usray-channels/1",
        "sampling_frequency_hz": float(fs),
        "t0_s": 0.0,
        "sound_speed_m_s": C,
        "center_frequency_hz": float(param.fc),
        "probe": probe,
        "transmits": [
            {"kind": k, key[k]: [float(p[0]), float(p[1])], "t0_s": t0}
            for (k, p, _), t0 in zip(tx, t0s)
        ],
        "scatterers": {"x_m": [p[0] * 1e-3 for p in pts], "z_m": [p[1] * 1e-3 for p in pts]},
        "speckle_disk": {"center_m": [disk[0] * 1e-3, disk[1] * 1e-3], "radius_m": disk[2] * 1e-3,
                         "per_mm2": disk[3], "rc": 0.1, "n": int(len(xs) - len(pts))},
        "generator": "tests/python/pymust_probes.py (pymust 0.1.9 simus, seed %d)" % SEED,
        "dropped_energy_fraction": dropped,
    }
    with open(os.path.join(out, name + ".json"), "w") as f:
        json.dump(meta, f, indent=1)

    # PyMUST's own image: rf2iq of each full record, dasmtx on the polar grid,
    # coherent sum over transmits, 20 log10(|IQ| / max).
    n_r, n_theta, zmax, width = grid
    X, Z, r, theta, origin_z = polar_grid(param, n_r, n_theta, zmax, width)
    p = copy.deepcopy(param)
    p.fnumber = fnumber
    # Diverging waves: dasmtx's default transmit distance, the earliest arrival
    # min_e(c·delay_e + |p − e|), which inside the insonified sector is the
    # circular wave's |p − v| − min_e|e − v| (PyMUST's virtual-transducer
    # option cannot be built for a convex array's diverging delays).
    # Focused waves, flat array: the virtual-transducer option
    # (param.useVirtualSource), the focused-wave model with its sign change at
    # the focus (the default earliest arrival is an edge wave beyond the focus).
    # Focused waves, convex array: pymust 0.1.9's convex virtual transducer
    # (vxdcr: fsolve with the element-to-virtual distance frozen at its first
    # guess) lies 0 to 0.85 mm off the circle of radius max_e|e - f| about the
    # focus (measured for C5-2v, focus (0, 45) mm), so it is no reference; the
    # default earliest arrival is exact before the focus, and the comparison
    # is made there only.
    focused = tx[0][0] == "focused"
    p.useVirtualSource = focused and np.isinf(param.radius)
    region = "insonified_before_focus" if focused and not p.useVirtualSource else "insonified"
    img = np.zeros(X.shape, complex)
    for (kind, point, dels), rf in zip(tx, rfs):
        iq = pymust.rf2iq(rf.astype(np.float64), p)
        p.TXdelay = dels  # dasmtx insists that a stored TXdelay equals DELAYS
        M = pymust.dasmtx(iq, X, Z, dels, p)
        img += (M @ iq.flatten(order="F")).reshape(X.shape, order="F")
    env = np.abs(img)
    db = 20 * np.log10(env / env.max())
    np.save(os.path.join(out, name + "_bmode_pymust.npy"), db.astype(np.float32))
    ref = {
        "grid": "polar",
        "origin_m": [0.0, float(origin_z)],
        "r_m": [float(r[0]), float(r[-1])],
        "theta_rad": [float(theta[0]), float(theta[-1])],
        "n_r": n_r,
        "n_theta": n_theta,
        "f_number": fnumber,
        "compare_region": region,
        "calls": "X,Z = impolgrid(...); per transmit: IQ = rf2iq(RF, param); "
                 "M = dasmtx(IQ, X, Z, dels, param) with param.fnumber = %g, "
                 "param.useVirtualSource = %s (linear interpolation); sum over transmits; "
                 "20 log10(|.|/max), not clipped" % (fnumber, p.useVirtualSource),
    }
    with open(os.path.join(out, name + "_bmode_pymust.json"), "w") as f:
        json.dump(ref, f, indent=1)
    print(f"{name}: {data.shape}, t0 {t0s}, dropped {dropped}", flush=True)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(SEED)

    # Phased array: diverging waves from PyMUST's txdelay(param, tilt, width).
    p4 = pymust.getparam("P4-2v")
    p4.c = C
    p4.fs = 4 * p4.fc
    L = (p4.Nelements - 1) * p4.pitch
    width = np.deg2rad(60.0)
    pts = [(0, 20), (0, 40), (0, 60), (-15, 35), (15, 50)]
    disk = (-12.0, 55.0, 7.0, 15.0)
    tx = []
    for tilt in np.deg2rad([-15.0, 0.0, 15.0]):
        dels = pymust.txdelay(p4, tilt, width)
        x0, z0 = sys.modules["pymust.txdelay"].angles2origo(L, np.array([[tilt]]), np.array([[width]]))
        tx.append(("diverging", (float(x0.ravel()[0]), float(z0.ravel()[0])), dels))
    grid = (160, 96, 70e-3, np.deg2rad(70.0))
    case("p4_diverging", p4, "phased", tx, pts, disk, grid, 0.0, out, rng)
    focus = (5e-3, 40e-3)
    tx = [("focused", focus, pymust.txdelay(focus[0], focus[1], p4))]
    case("p4_focused", p4, "phased", tx, pts, disk, grid, 0.0, out, rng)

    # Convex array: diverging waves from virtual sources behind the arc.
    c5 = pymust.getparam("C5-2v")
    c5.c = C
    c5.fs = 4 * c5.fc
    pts = [(0, 25), (0, 45), (0, 65), (-15, 40), (18, 55)]
    disk = (10.0, 35.0, 7.0, 15.0)
    tx = []
    for x0 in [-10e-3, 0.0, 10e-3]:
        v = (x0, -25e-3)
        tx.append(("diverging", v, pymust.txdelay(v[0], v[1], c5)))
    grid = (160, 128, 70e-3, None)
    case("c5_diverging", c5, "convex", tx, pts, disk, grid, 1.0, out, rng)
    focus = (0.0, 45e-3)
    tx = [("focused", focus, pymust.txdelay(focus[0], focus[1], c5))]
    case("c5_focused", c5, "convex", tx, pts, disk, grid, 1.0, out, rng)


if __name__ == "__main__":
    main()
