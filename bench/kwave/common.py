"""Geometry, medium and source of usray's full-wave benchmark (tier b, bench/README.md).

A copy of ../shared/tools/kwave/common.py with two ring geometries (GEOMS), per-case pulse
lengths and every catalogue effect of `usray diagnose` as a case."""
import os
import numpy as np

# ---- grid -------------------------------------------------------------------------
# KWAVE_GRID_DIVISOR=G refines the grid G times on each axis (same physical domain, array row
# and PML thickness in points; the time step is divided by G too, keeping the CFL number): the
# benchmark's data are made at G = 1 (7.9 points per wavelength, the 0.15 mm wall two cells);
# G = 2 (16 points, four cells, about 9x the cost) checks what the grid puts in them
# (docs/diagnosis.md, Known limits: "k-Wave's grid").
GRID_DIVISOR = int(os.environ.get("KWAVE_GRID_DIVISOR", "1"))
DX = 0.075e-3 / GRID_DIVISOR  # grid spacing [m]  (PPW = 1480/2.5e6/DX = 7.9 at G = 1)
NZ_IN, NX_IN = 360 * GRID_DIVISOR, 320 * GRID_DIVISOR   # interior grid (axis0 = z, axis1 = x)
PML = 20                      # PML points per side, outside the interior (pml_inside=False)
PML_ALPHA = 2.0
J0 = 8 * GRID_DIVISOR         # interior row holding the array (z = 0)
# The k-space operator is exact for a wave at its reference speed C_REF (Tabei et al. 2002;
# k-Wave manual §2.5): C_REF is the water's, so the echoes' travel times carry no time-stepping
# error. With C_REF = 1600 m/s (the wall's) the step delayed echoes in 1480 m/s water by about
# 0.08% of their travel time (group-velocity error (k dt C_REF/2)^2 (1 - (c/C_REF)^2)/2), which
# read as a 0.2% slower water (docs/diagnosis.md, Known limits). Stable: CFL 0.27 < 0.75 at
# C_REF/c_max = 0.925. KWAVE_DT_DIVISOR=N runs at 1/N of the time step (same 50 us, same output
# grid) to check that the step no longer matters; it defaults to the grid divisor.
DT_DIVISOR = int(os.environ.get("KWAVE_DT_DIVISOR", str(GRID_DIVISOR)))
DT = 12.5e-9 / DT_DIVISOR     # time step (fs_sim = 80 MHz; CFL = 1600*DT/DX = 0.267)
NT = 4000 * DT_DIVISOR        # 50 us of simulated time
C_REF = 1480.0                # k-space / PML reference speed (the water's), identical in every run
z = (np.arange(NZ_IN) - J0) * DX                  # row centres
x = (np.arange(NX_IN) - NX_IN / 2 + 0.5) * DX      # column centres (x=0 between two columns)

# ---- probe ------------------------------------------------------------------------
NEL, PITCH, WIDTH = 64, 0.3e-3, 0.27e-3
XEL = (np.arange(NEL) - (NEL - 1) / 2) * PITCH
F0, NCYC = 2.5e6, 3
T_BURST = NCYC / F0
SIGMA_T = T_BURST / 6          # k-Wave tone_burst Gaussian envelope: x in [-3,3] over the burst, sigma = 1
NCYC_LONG = 5                  # the pulse_length cases' burst (sigma 5/3 as long)
# The center_frequency cases' bursts (3 cycles; the data still declare F0, the probe's nominal
# centre): 12% low on g1, 12% high on the disk g4.
F0_LOW, F0_HIGH = 2.2e6, 2.8e6
T_LEAD = 2.5e-6                # sim time at which the (x=0) wavefront centre leaves the array = our t=0
N_LEAD = int(round(T_LEAD / DT))   # 200 (room for the 5-cycle burst's leading 4 sigma + max delay)
C_TX = 1480.0                  # speed the "scanner" uses for its transmit delays (all cases)
SRC_LEN = 400 * DT_DIVISOR     # source samples (5 us) -- covers lead + max delay + 4 sigma

def element_weights():
    """(NEL, NX_IN) area weights of each element over the cells of the array row."""
    W = np.zeros((NEL, NX_IN))
    lo_c, hi_c = x - DX / 2, x + DX / 2
    for i, xc in enumerate(XEL):
        lo, hi = xc - WIDTH / 2, xc + WIDTH / 2
        W[i] = np.clip(np.minimum(hi, hi_c) - np.maximum(lo, lo_c), 0, None) / DX
    return W

def pulse(t, ncyc=NCYC, f0=F0):
    """k-Wave tone_burst(fs, f0, ncyc) written analytically about its envelope centre (t = 0):
    -sin(2 pi f0 t) * exp(-t^2 / (2 sigma^2)), sigma = ncyc / (6 f0), truncated at |t| = 4 sigma."""
    sigma = ncyc / f0 / 6
    s = -np.sin(2 * np.pi * f0 * t) * np.exp(-t ** 2 / (2 * sigma ** 2))
    return np.where(np.abs(t) <= 4 * sigma, s, 0.0)

# ---- target -----------------------------------------------------------------------
# Two ring geometries (centre (x, z) and outer radius, m); both inside the grid above.
GEOMS = {
    "g1": dict(centre=(0.0, 16e-3), r_out=5e-3),        # 5 mm ring on axis at 16 mm
    "g2": dict(centre=(2e-3, 13e-3), r_out=3.5e-3),     # 3.5 mm ring off axis at 13 mm
    # Held out: chosen, with its cases' magnitudes, before any diagnosis ran on it, and
    # not tuned on afterwards (docs/diagnosis.md, tier (b)). A 4 mm ring off axis at 18 mm
    # with a 0.3 mm wall; a slower water, a stronger attenuation, a weaker gain.
    "g3": dict(centre=(-2.5e-3, 18e-3), r_out=4e-3),
    # Held out too, and not a ring: a solid 3 mm disk of the wall's material (1600 m/s,
    # 1.76 MRayl) off axis at 15 mm, which refracts what passes through it. Chosen, with its
    # cases' magnitudes, before any diagnosis ran on it.
    "g4": dict(centre=(1.5e-3, 15e-3), r_out=3e-3),
}
RING_C = GEOMS["g1"]["centre"]
R_OUT = GEOMS["g1"]["r_out"]
C_W, RHO_W = 1480.0, 1000.0
# KWAVE_WALL_C sets another wall speed, its density keeping the wall's 1.76 MRayl (e.g. 1480: no
# refraction at the wall; docs/diagnosis.md, Known limits, "k-Wave's grid").
C_T = float(os.environ.get("KWAVE_WALL_C", "1600"))
RHO_T = 1100.0 * 1600.0 / C_T

def ring_fraction(r_in, r_out, nsub=10, centre=None):
    """Area fraction of each interior cell covered by the annulus r_in < r < r_out about `centre`."""
    RING_C = centre if centre is not None else GEOMS["g1"]["centre"]
    f = np.zeros((NZ_IN, NX_IN))
    jz = np.where(np.abs(z - RING_C[1]) < r_out + 2 * DX)[0]
    jx = np.where(np.abs(x - RING_C[0]) < r_out + 2 * DX)[0]
    off = (np.arange(nsub) + 0.5) / nsub - 0.5
    ZZ = z[jz][:, None, None, None] + off[None, None, :, None] * DX
    XX = x[jx][None, :, None, None] + off[None, None, None, :] * DX
    r = np.sqrt((XX - RING_C[0]) ** 2 + (ZZ - RING_C[1]) ** 2)
    inside = (r > r_in) & (r < r_out)
    f[np.ix_(jz, jx)] = inside.mean(axis=(2, 3))
    return f

def mix(f, c_bg, rho_bg, c_t=C_T, rho_t=RHO_T):
    """Partial-volume mixing: density and compressibility averaged by area fraction."""
    rho = (1 - f) * rho_bg + f * rho_t
    kap = (1 - f) / (rho_bg * c_bg ** 2) + f / (rho_t * c_t ** 2)
    return np.sqrt(1 / (rho * kap)), rho

# Each case: geometry, wall thickness (None: no target), water speed, attenuation (dB/cm/MHz, in
# water and wall), lumen speckle, pulse cycles and centre frequency (`f0`); `ref` names the background run subtracted from it
# (same water and pulse, no ring); `gain_db_cm` a depth gain applied in finalize.py (a scanner's
# TGC acts on the received signal, not on the field).
# The modelled wall, 0.15 mm whatever the grid (two cells at G = 1, four at G = 2). KWAVE_WALL_M
# sets another (e.g. 0.45e-3) for every case that has the modelled wall, to see what a thicker wall
# on the same grid gives (docs/diagnosis.md, Known limits, "k-Wave's grid").
THIN = float(os.environ.get("KWAVE_WALL_M", "0.15e-3"))
CASES = {
    "ref1480":  dict(wall=None, c_w=1480.0, alpha=0.0, speckle=False),
    "ref1520":  dict(wall=None, c_w=1520.0, alpha=0.0, speckle=False),
    "refatt":   dict(wall=None, c_w=1480.0, alpha=0.5, speckle=False),
    "refpulse": dict(wall=None, c_w=1480.0, alpha=0.0, speckle=False, ncyc=NCYC_LONG),
    "ref1450":  dict(wall=None, c_w=1450.0, alpha=0.0, speckle=False),
    "refatt07": dict(wall=None, c_w=1480.0, alpha=0.7, speckle=False),
    "ref1500":  dict(wall=None, c_w=1500.0, alpha=0.0, speckle=False),
    "reff22":   dict(wall=None, c_w=1480.0, alpha=0.0, speckle=False, f0=F0_LOW),
    "reff28":   dict(wall=None, c_w=1480.0, alpha=0.0, speckle=False, f0=F0_HIGH),
}
def ring_cases(g, wall, thick, speed, speed_ref, alpha, alpha_ref, gain_db_cm):
    """No effect and six effects on ring `g` modelled with a `wall` (m): a `thick` wall (none
    when `thick` is None), water at `speed` (background run `speed_ref`), attenuation `alpha`
    (`alpha_ref`), speckle in the lumen (in a solid target, inside it), the long pulse, a
    depth gain."""
    base = dict(geom=g, wall=wall, c_w=1480.0, alpha=0.0, speckle=False, ref="ref1480")
    walls = {} if thick is None else {f"{g}_wall": {**base, "wall": thick}}
    return {
        f"{g}_none":    base,
        **walls,
        f"{g}_speed":   {**base, "c_w": speed, "ref": speed_ref},
        f"{g}_atten":   {**base, "alpha": alpha, "ref": alpha_ref},
        f"{g}_speckle": {**base, "speckle": True},
        f"{g}_pulse":   {**base, "ref": "refpulse", "ncyc": NCYC_LONG},
        f"{g}_gain":    {**base, "raw": f"{g}_none", "gain_db_cm": gain_db_cm},
    }

for g in ("g1", "g2"):
    CASES.update(ring_cases(g, THIN, 0.9e-3, 1520.0, "ref1520", 0.5, "refatt", 3.0))
G3_WALL = 0.3e-3               # g3's modelled wall (bench/kwave/g3.toml)
CASES.update(ring_cases("g3", G3_WALL, 1.0e-3, 1450.0, "ref1450", 0.7, "refatt07", 2.0))
# g4, the solid disk (its "wall" is its radius): every effect but a wall's thickness.
CASES.update(ring_cases("g4", GEOMS["g4"]["r_out"], None, 1500.0, "ref1500", 0.5, "refatt", 2.5))
# A probe whose centre frequency is not its nominal one, on a ring and on the disk.
CASES["g1_freq"] = {**CASES["g1_none"], "ref": "reff22", "f0": F0_LOW}
CASES["g4_freq"] = {**CASES["g4_none"], "ref": "reff28", "f0": F0_HIGH}
ALPHA_POWER = 1.0              # y = 1 with alpha_mode = 'no_dispersion' (exactly dB/cm/MHz)
SPECKLE_SEED, SPECKLE_FRAC, SPECKLE_STD, SPECKLE_CLIP = 21, 0.15, 0.02, 0.04

def build_medium(case):
    p = CASES[case]
    c = np.full((NZ_IN, NX_IN), p["c_w"]); rho = np.full((NZ_IN, NX_IN), RHO_W)
    info = {}
    if p["wall"] is not None:
        g = GEOMS[p["geom"]]
        f = ring_fraction(g["r_out"] - p["wall"], g["r_out"], centre=g["centre"])
        c, rho = mix(f, p["c_w"], RHO_W)
        info["wall_cells_equiv"] = float(f.sum())
        if p["speckle"]:
            rng = np.random.default_rng(SPECKLE_SEED)
            if p["wall"] >= g["r_out"]:                             # a solid disk: inside it
                cand = f >= 1.0
            else:
                fin = ring_fraction(0.0, g["r_out"] - p["wall"], centre=g["centre"])   # lumen fraction
                cand = (fin >= 1.0) & (f == 0)                      # cells wholly inside the lumen
            u = rng.random((NZ_IN, NX_IN))
            dc = np.clip(rng.normal(0, SPECKLE_STD, (NZ_IN, NX_IN)), -SPECKLE_CLIP, SPECKLE_CLIP)
            drho = np.clip(rng.normal(0, SPECKLE_STD, (NZ_IN, NX_IN)), -SPECKLE_CLIP, SPECKLE_CLIP)
            sel = cand & (u < SPECKLE_FRAC)
            c = np.where(sel, c * (1 + dc), c); rho = np.where(sel, rho * (1 + drho), rho)
            info.update(n_scatterer_cells=int(sel.sum()), n_lumen_cells=int(cand.sum()),
                        dc_std=float(dc[sel].std()), drho_std=float(drho[sel].std()))
    return c.astype(np.float32), rho.astype(np.float32), info
