"""Independent analytic references from docs/physics.md, written without the simulator's code.

Flat seafloor at altitude h (docs/physics.md §3, eq. 2):

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


def flat_floor_g(r_m, h=10.0, mu_db=-27.0, alpha_db_m=0.096, sigma=None, gamma=None, **beam):
    """g(R) of eq. (2) on the slant ranges ``r_m`` (all ≥ h); ``sigma(cos θi)``: another law than Lambert μ;
    ``gamma(u_fwd, u_side, u_down)``: another one-way pattern than the membrane of ``beam``."""
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
        pattern = gamma_membrane(u_f, u_s, u_d, **beam) if gamma is None else gamma(u_f, u_s, u_d)
        az = np.trapezoid(pattern ** 4, phi, axis=1)
        rr = r[:, 0]
        cos_i = h / rr
        sig = mu * cos_i ** 2 if sigma is None else sigma(cos_i)
        out[a:a + 256] = sig * 10 ** (-2 * alpha_db_m * rr / 10) * rr ** -3 * az
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


def down_looking_flat_floor(r_m, h, azimuth_b4, alpha_db_m, pulse_extent_m, mu_db=-27.0, r_max=30.0, n=40001):
    """A down-looking beam over a flat Lambert floor at altitude h: E[I] at slant ranges ``r_m`` for a rectangular
    pulse, ∫ g over [R − cτ/2, R], g(R) = μ·(h/R)²·10^(−2αR/10)/R³·∫ b⁴(θ, φ) dφ with cos θ = h/R;
    ``azimuth_b4(theta)`` (k,) → the azimuth integral of b⁴ at each θ (rad)."""
    grid = np.linspace(h, r_max, n)
    g = (azimuth_b4(np.arccos(h / grid)) * 10 ** (mu_db / 10) * (h / grid) ** 2
         * 10 ** (-2 * alpha_db_m * grid / 10) / grid ** 3)
    cum = np.concatenate([[0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])
    return np.interp(r_m, grid, cum) - np.interp(np.asarray(r_m) - pulse_extent_m, grid, cum)


def tvg_flat_floor(r_m, h=10.0, mu_db=-27.0, pulse_extent_m=0.075, f0=400e3, c=1500.0, lx=0.19, ly=0.0038,
                   tilt_deg=20.0):
    """docs/physics.md §3: with perfect TVG a Lambertian flat floor follows μ·h²·Φ_eq·(cτ/2)·Γ_el⁴/ρ.

    Φ_eq = 2λ/(3·lx); Γ_el the elevation pattern sinc(k·ly/2·sin(β − δ)) at the depression
    β = asin(h/R); ρ = √(R² − h²).
    """
    r = np.asarray(r_m, dtype=float)
    lam = c / f0
    k = 2 * np.pi / lam
    beta = np.arcsin(h / r)
    g_el = np.sinc(k * ly / 2 * np.sin(beta - np.radians(tilt_deg)) / np.pi)
    phi_eq = 2 * lam / (3 * lx)
    rho = np.sqrt(r ** 2 - h ** 2)
    return 10 ** (mu_db / 10) * h ** 2 * phi_eq * pulse_extent_m * g_el ** 4 / rho


def ainslie_mccolm_db_per_km(f_hz, t_c=10.0, s_ppt=35.0, depth_m=0.0, ph=8.0):
    """Ainslie & McColm (1998), J. Acoust. Soc. Am. 103(3), 1671: a simplified absorption formula.

    An independent check of Francois–Garrison (docs/physics.md §3: within 10 % of it).
    """
    f = f_hz / 1e3
    z = depth_m / 1e3
    f1 = 0.78 * np.sqrt(s_ppt / 35) * np.exp(t_c / 26)
    f2 = 42 * np.exp(t_c / 17)
    return (0.106 * f1 * f * f / (f1 * f1 + f * f) * np.exp((ph - 8) / 0.56)
            + 0.52 * (1 + t_c / 43) * (s_ppt / 35) * f2 * f * f / (f2 * f2 + f * f) * np.exp(-z / 6)
            + 0.00049 * f * f * np.exp(-(t_c / 27 + z / 17)))


def kirchhoff_monostatic(theta_rad, r0, slope_rms):
    """Gaussian-facet Kirchhoff backscatter, docs/physics.md §10 (Jackson & Richardson 2007, §13.2):
    σ(θ) = R0²/(8π s²) · sec⁴θ · exp(−tan²θ / (2 s²))."""
    t = np.asarray(theta_rad, dtype=float)
    return r0 ** 2 / (8 * np.pi * slope_rms ** 2) / np.cos(t) ** 4 * np.exp(-np.tan(t) ** 2 / (2 * slope_rms ** 2))


def sidescan_gamma(u, ping):
    """Γ of the default side-scan on a line along +x (heading 90°: forward +x, starboard −y, down −z)."""
    return gamma_membrane(u[:, 0], np.abs(u[:, 1]), -u[:, 2])


def sphere_quadrature(a, centre, positions, alpha_db_m, mu_db, n=240, gamma=sidescan_gamma):
    """Echo energy of a Lambertian sphere (docs/physics.md §7b), per ping:

        E = ∫ Γ⁴(u) μ cos²θi 10^(−2αR/10) / R⁴ dA

    over its lit surface above z = 0 (the floor), midpoint rule on an n × 2n (polar, azimuth) grid; for a sphere
    small against the beam E → Γ⁴·10^(−2αR/10)·(2πa²μ/3)/R⁴. ``positions`` (pings, 3) the sonar's;
    ``gamma(u, ping)`` the one-way gain of world unit directions u (m, 3) at a ping."""
    th = (np.arange(n) + 0.5) * np.pi / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    T, P = np.meshgrid(th, ph, indexing="ij")
    nrm = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    dA = (a * a * np.sin(T) * (np.pi / n) ** 2).ravel()
    pt = np.asarray(centre) + a * nrm
    out = []
    for i, p in enumerate(positions):
        v = pt - p
        R = np.linalg.norm(v, axis=1)
        u = v / R[:, None]
        ci = -(u * nrm).sum(axis=1)
        lit = (ci > 0) & (pt[:, 2] >= 0.0)
        g = gamma(u, i)
        f = g ** 4 * 10 ** (mu_db / 10) * ci ** 2 * 10 ** (-2 * alpha_db_m * R / 10) / R ** 4 * dA
        out.append(f[lit].sum())
    return np.array(out)


def patch_quadrature(size, centre, positions, alpha_db_m, mu_db, gamma, n=200):
    """Echo energy of a flat Lambertian rectangle ``size`` = (along x, along y) m at ``centre`` (x, y, z), facing up,
    per ping: E = ∫ Γ⁴(u) μ cos²θi 10^(−2αR/10) / R⁴ dA (docs/physics.md eq. 1 with dA = R²dΩ/cos θi, σ = μ cos²θi
    monostatic), midpoint rule on an n × n grid. ``positions`` (pings, 3) the sonar's; ``gamma(u, ping)`` the one-way
    gain of world unit directions u (m, 3) at a ping."""
    fx, fy = ((np.arange(n) + 0.5) / n - 0.5) * size[0], ((np.arange(n) + 0.5) / n - 0.5) * size[1]
    X, Y = np.meshgrid(centre[0] + fx, centre[1] + fy, indexing="ij")
    pt = np.stack([X.ravel(), Y.ravel(), np.full(X.size, float(centre[2]))], axis=1)
    dA = size[0] * size[1] / (n * n)
    out = []
    for i, p in enumerate(positions):
        v = pt - p
        R = np.linalg.norm(v, axis=1)
        u = v / R[:, None]
        ci = np.maximum(-u[:, 2], 0.0)
        g = gamma(u, i)
        out.append(np.sum(g ** 4 * 10 ** (mu_db / 10) * ci ** 2 * 10 ** (-2 * alpha_db_m * R / 10) / R ** 4 * dA))
    return np.array(out)


def cylinder_quadrature(rho, length, centre, axis, positions, alpha_db_m, mu_db, gamma, n_t=1000, n_phi=128):
    """Echo energy of a closed Lambertian cylinder (radius ``rho``, ``length`` along ``axis``, centred at ``centre``,
    m) per ping: E = ∫ Γ⁴(u) μ cos²θi 10^(−2αR/10) / R⁴ dA over its side and both end caps, cos θi = max(−u·n, 0)
    (a convex surface shadows only itself, which cos θi > 0 excludes); midpoint rules, the side on an n_t × n_phi
    grid (dA = ρ dφ dt), each cap on n_phi/2 rings × n_phi sectors of equal area."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(a, [0.0, 0.0, 1.0])
    e1 = e1 / np.linalg.norm(e1) if np.linalg.norm(e1) > 1e-9 else np.array([1.0, 0.0, 0.0])
    e2 = np.cross(a, e1)
    t = ((np.arange(n_t) + 0.5) / n_t - 0.5) * length
    phi = 2 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    T, P = np.meshgrid(t, phi, indexing="ij")
    normal = np.cos(P).ravel()[:, None] * e1 + np.sin(P).ravel()[:, None] * e2
    pts = [np.asarray(centre, float) + T.ravel()[:, None] * a + rho * normal]
    normals, areas = [normal], [np.full(T.size, length / n_t * rho * 2 * np.pi / n_phi)]
    r = rho * np.sqrt((np.arange(n_phi // 2) + 0.5) / (n_phi // 2))          # rings of equal area
    R, P = np.meshgrid(r, phi, indexing="ij")
    disk = R.ravel()[:, None] * (np.cos(P).ravel()[:, None] * e1 + np.sin(P).ravel()[:, None] * e2)
    for sign in (-1.0, 1.0):
        pts.append(np.asarray(centre, float) + sign * 0.5 * length * a + disk)
        normals.append(np.tile(sign * a, (disk.shape[0], 1)))
        areas.append(np.full(disk.shape[0], np.pi * rho ** 2 / disk.shape[0]))
    pt, normal, dA = np.concatenate(pts), np.concatenate(normals), np.concatenate(areas)
    out = []
    for i, p in enumerate(positions):
        v = pt - p
        R = np.linalg.norm(v, axis=1)
        u = v / R[:, None]
        ci = np.maximum(-(u * normal).sum(axis=1), 0.0)
        out.append(np.sum(gamma(u, i) ** 4 * 10 ** (mu_db / 10) * ci ** 2 * 10 ** (-2 * alpha_db_m * R / 10) / R ** 4
                          * dA))
    return np.array(out)


def hemisphere_integral(f, n_theta=1200, n_phi=2048):
    """∫ f dΩ over the hemisphere in front of an aperture by brute quadrature in spherical angles about its axis:
    θ from the axis on Gauss–Legendre nodes over [0, π/2], φ on a uniform periodic grid (spectrally exact for the
    periodic integrand). ``f(u, v, w)``: direction cosines u = sin θ cos φ, v = sin θ sin φ along the aperture's
    sides and w = cos θ along its axis."""
    x, wt = np.polynomial.legendre.leggauss(n_theta)
    theta, wt = np.pi / 4 * (x + 1), np.pi / 4 * wt
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    total = 0.0
    for i in range(0, n_theta, 250):
        st = np.sin(theta[i:i + 250])[:, None]
        val = f(st * np.cos(phi), st * np.sin(phi), np.cos(theta[i:i + 250])[:, None] + 0 * phi)
        total += float(np.sum(wt[i:i + 250] * st[:, 0] * val.sum(axis=1)) * 2 * np.pi / n_phi)
    return total


def directivity_index_db(pattern, n_theta=1200, n_phi=2048):
    """DI = 10·log10(4π / ∫ b² dΩ) (docs/physics.md §14) by :func:`hemisphere_integral`; ``pattern(u, v)``: the
    one-way pressure b at direction cosines u, v along the aperture's sides."""
    return 10 * np.log10(4 * np.pi / hemisphere_integral(lambda u, v, w: pattern(u, v) ** 2, n_theta, n_phi))


def membrane_pattern(length_m, height_m, wavelength_m):
    """b(u, v) = sinc(k·lx/2·u)·sinc(k·ly/2·v) of a rectangular membrane (docs/physics.md §2)."""
    a, b = np.pi * length_m / wavelength_m, np.pi * height_m / wavelength_m
    return lambda u, v: np.sinc(a * u / np.pi) * np.sinc(b * v / np.pi)


def coates_db(f_hz, wind, shipping=0.5, thermal=True):
    """Ambient noise spectral density, dB re 1 µPa²/Hz: Coates (1990) as summarised by Stojanovic (2007), the sum of
    the turbulence, shipping, wind and thermal terms (docs/physics.md §14)."""
    f = f_hz / 1e3
    terms = [17 - 30 * np.log10(f), 40 + 20 * (shipping - 0.5) + 26 * np.log10(f) - 60 * np.log10(f + 0.03),
             50 + 7.5 * np.sqrt(wind) + 20 * np.log10(f) - 40 * np.log10(f + 0.4)]
    if thermal:
        terms.append(-15 + 20 * np.log10(f))
    return 10 * np.log10(sum(10 ** (t / 10) for t in terms))
