"""Independent analytic references from PHYSICS.md, written without the simulator's code.

Flat seafloor at altitude h (PHYSICS.md §3, eq. 2):

    g(R) = σ(h/R) · 10^(−2αR/10) · R⁻³ · ∫ Γ⁴(u(R, φ)) dφ,   E[I](t) = ∫ g(R) |p(t − 2R/c)|² dR

φ is the ground azimuth about nadir over the full circle (φ = 0 towards the side
looked at), u the unit vector from the sonar to the floor point, Γ the baffled
rectangular-membrane directivity. Everything here is plain NumPy quadrature.
"""
import numpy as np


def gamma_membrane(u_fwd, u_side, u_down, f0=400e3, c=1500.0, lx=0.19, ly=0.0038, tilt_deg=20.0):
    """One-way directivity for unit direction components (forward, outboard side, down)."""
    k = 2 * np.pi * f0 / c
    d = np.radians(tilt_deg)
    along = u_fwd
    height = -u_side * np.sin(d) + u_down * np.cos(d)
    bore = u_side * np.cos(d) + u_down * np.sin(d)

    def sinc(x):
        return np.sinc(x / np.pi)

    return sinc(k * lx / 2 * along) * sinc(k * ly / 2 * height) * (bore > 0)


def _phi_grid():
    dense = np.linspace(-0.15, 0.15, 3001)
    coarse = np.linspace(-np.pi, np.pi, 8001)
    return np.unique(np.concatenate([dense, coarse]))


def flat_floor_g(r_m, h=10.0, mu_db=-27.0, alpha_db_m=0.096, **beam):
    """g(R) of eq. (2) on the slant ranges ``r_m`` (all ≥ h)."""
    r_m = np.asarray(r_m, dtype=float)
    phi = _phi_grid()
    out = np.empty_like(r_m)
    mu = 10 ** (mu_db / 10)
    for a in range(0, r_m.size, 256):
        r = r_m[a:a + 256, None]
        rho = np.sqrt(np.maximum(r ** 2 - h ** 2, 0.0))
        u_f = rho * np.sin(phi) / r
        u_s = rho * np.cos(phi) / r
        u_d = np.broadcast_to(h / r, u_f.shape)
        az = np.trapezoid(gamma_membrane(u_f, u_s, u_d, **beam) ** 4, phi, axis=1)
        rr = r[:, 0]
        cos_i = h / rr
        out[a:a + 256] = mu * cos_i ** 2 * 10 ** (-2 * alpha_db_m * rr / 10) * rr ** -3 * az
    return out


def flat_floor_expected_intensity(r_cell_end_m, pulse_extent_m=0.075, h=10.0, dr=0.01, **kw):
    """E[I] at the times t = 2R/c for a rectangular pulse: ∫ g over [R − cτ/2, R] (R ≥ h).

    Parameters
    ----------
    r_cell_end_m : (n,) float
        R = c·t/2 of each sample.
    pulse_extent_m : float
        cτ/2 of the rectangular pulse.
    """
    r_cell_end_m = np.asarray(r_cell_end_m, dtype=float)
    grid = np.arange(h, r_cell_end_m.max() + dr, dr)
    g = flat_floor_g(grid, h=h, **kw)
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])

    def G(x):
        return np.interp(np.clip(x, h, grid[-1]), grid, cum)

    return G(r_cell_end_m) - G(r_cell_end_m - pulse_extent_m)
