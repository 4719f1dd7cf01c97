import sys, json, os, numpy as np
from scipy.signal import hilbert
import os; HERE = os.path.dirname(os.path.abspath(__file__)); sys.path.insert(0, HERE); SCRATCH = os.environ.get('KWAVE_SCRATCH', os.path.join(HERE, 'scratch'))
from common import *

# KWAVE_ANGLES="0" (comma-separated degrees) finalizes only those transmits, e.g. to diagnose the 0 deg
# runs of a finer grid alone (docs/diagnosis.md, Known limits, "k-Wave's grid").
ANGLES = [float(a) for a in os.environ.get("KWAVE_ANGLES", "-8,0,8").split(",")]
FS_OUT = 40e6
DEC = int(round(1 / (FS_OUT * DT)))          # 2
NS_OUT = (NT - N_LEAD) // DEC                # 1920
T0_OUT = DT / 2   # k-Wave additive source: sample s[n] is injected over step n-1 -> n, i.e. the wave leaves dt/2 early


def load(case, a):
    return np.load(f"{SCRATCH}/raw/{case}_{a:+.0f}.npz")

def channels(case):
    """[n_tx, n_el, n_samples] scattered field (total - same-background homogeneous run), 40 MHz, t0 = 0."""
    p = CASES[case]
    ref, raw = p["ref"], p.get("raw", case)
    out = []
    for a in ANGLES:
        d = load(raw, a)["rf"].astype(np.float64) - load(ref, a)["rf"].astype(np.float64)
        out.append(d[:, N_LEAD: N_LEAD + DEC * NS_OUT: DEC])
    out = np.array(out)
    if p.get("gain_db_cm"):
        # A scanner's depth gain (usray's acquisition.depth_gain_db_per_cm, effects.rs::depth_gain):
        # amplitude x 10^(g * d / 20) at the depth d = c t / 2 (cm) the scanner assigns to time t.
        t = T0_OUT + np.arange(NS_OUT) / FS_OUT
        out = out * 10 ** (p["gain_db_cm"] * (C_TX * t / 2 * 100) / 20)
    return np.ascontiguousarray(out.astype(np.float32))

def das(ch, c, fs=FS_OUT, t0=None, xs=None, zs=None, fnum=1.5, angles=ANGLES):
    """Plain-numpy DAS of plane-wave data; returns complex image per transmit [n_tx, nz, nx]."""
    t0 = T0_OUT if t0 is None else t0
    xs = np.arange(-10e-3, 10e-3 + 1e-9, 0.05e-3) if xs is None else xs
    zs = np.arange(1e-3, 30e-3 + 1e-9, 0.05e-3) if zs is None else zs
    Z, X = np.meshgrid(zs, xs, indexing='ij')
    imgs = []
    for it, a in enumerate(angles):
        th = np.deg2rad(a)
        an = hilbert(ch[it].astype(np.float64), axis=-1)
        ttx = (X * np.sin(th) + Z * np.cos(th)) / c
        img = np.zeros(Z.shape, complex)
        for e, xe in enumerate(XEL):
            dxe = X - xe
            t = ttx + np.sqrt(dxe ** 2 + Z ** 2) / c
            s = (t - t0) * fs
            i0 = np.floor(s).astype(int); fr = s - i0
            ok = (i0 >= 0) & (i0 < ch.shape[-1] - 1) & (np.abs(dxe) <= Z / (2 * fnum) + PITCH)
            i0c = np.clip(i0, 0, ch.shape[-1] - 2)
            v = an[e, i0c] * (1 - fr) + an[e, i0c + 1] * fr
            img += np.where(ok, v, 0)
        imgs.append(img)
    return np.array(imgs), xs, zs

def wall_depth(ch, c, a_idx, zlo=10.5e-3, zhi=14e-3):
    zs = np.arange(zlo, zhi, 0.005e-3)
    img, _, _ = das(ch, c, xs=np.array([0.0]), zs=zs, angles=[ANGLES[a_idx]])
    env = np.abs(img[0][:, 0])
    k = np.argmax(env)
    if 0 < k < len(zs) - 1:
        y0, y1, y2 = env[k - 1], env[k], env[k + 1]
        dk = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    else:
        dk = 0
    return zs[k] + dk * 0.005e-3, env.max()

def bmode_png(ch, c, path, title, r_in=None, centre=RING_C, r_out=R_OUT):
    import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot as plt
    imgs, xs, zs = das(ch, c)
    comp = np.abs(imgs.sum(0))
    db = 20 * np.log10(comp / comp.max() + 1e-12)
    fig, axs = plt.subplots(1, 2, figsize=(11, 7.5))
    for k, ax in enumerate(axs):
        ax.imshow(db, cmap='gray', vmin=-60, vmax=0, extent=[xs[0]*1e3, xs[-1]*1e3, zs[-1]*1e3, zs[0]*1e3], aspect='equal')
        if k == 1:
            th = np.linspace(0, 2*np.pi, 400)
            for r in [r_out] + ([r_in] if r_in else []):
                ax.plot((centre[0] + r*np.cos(th))*1e3, (centre[1] + r*np.sin(th))*1e3, 'r--', lw=0.6)
        ax.set_xlabel('x [mm]'); ax.set_ylabel('z [mm]')
    axs[0].set_title(title); axs[1].set_title('same + true ring outline (red), beamformed at c=%.0f' % c)
    fig.tight_layout(); fig.savefig(path, dpi=90); plt.close(fig)
    return db
