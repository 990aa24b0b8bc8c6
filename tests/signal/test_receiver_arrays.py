"""Receiver arrays (docs/physics.md §18a): every element on its own bistatic path, checked against the closed form
τ_k = (|X − p_tx| + |X − p_k|)/c and phase −2π·f0·τ_k for a point scatterer; speckle coherent across elements; a
one-element array at the transmitter is the plain side-scan, bit for bit; the element dimension in the files;
refusals in one line."""
import dataclasses

import numpy as np
import pytest
import trimesh
import xarray as xr

import sonar_embree as se
from sonar_embree.runs.cli import main
from sonar_embree.errors import ConfigError
from sonar_embree.propagation.clutter import clutter_field
from sonar_embree.signal.interferometry import cross_spectrum

C, F0, B = 1500.0, 100e3, 20e3


def _floor_scene():
    sc = se.Scene()
    sc.add(se.seafloor.flat(size_m=(20, 50)), material=se.Material(backscatter_db=-20), label="seafloor")
    return sc


def _point_scene():
    """A 1 m² tile at 14 m across whose only echoes are its clutter scatterers (point targets, known positions)."""
    sc = se.Scene()
    tile = trimesh.Trimesh([[-0.5, -14.5, 0], [0.5, -14.5, 0], [0.5, -13.5, 0], [-0.5, -13.5, 0]],
                           [[0, 1, 2], [0, 2, 3]])
    clutter = se.Clutter(density_per_m2=3.0, strength_db=-20.0, spread_db=0.0)
    sc.add(tile, material=se.Material(backscatter_db=-120, clutter=clutter), label="tile")
    return sc


def _interpolate(z, x, half=24):
    """z at fractional sample x: a Hann-windowed sinc over ±``half`` samples (z is oversampled twice)."""
    n = np.arange(int(x) - half, int(x) + half + 1)
    w = np.sinc(x - n) * np.cos(0.5 * np.pi * (x - n) / (half + 1)) ** 2
    return np.sum(z[n] * w)


def _membrane(u, length_m, height_m, tilt_deg):
    """The starboard membrane's one-way amplitude pattern for world unit directions u (n, 3) of a sonar heading
    east (+x): sinc(L·u_x/λ)·sinc(H·u_e/λ), u_e along the elevation axis of the boresight depressed by the tilt
    (docs/physics.md §2); 0 behind it."""
    t = np.radians(tilt_deg)
    bore, elev = np.array([0.0, -np.cos(t), -np.sin(t)]), np.array([0.0, np.sin(t), -np.cos(t)])
    lam = C / F0
    return np.where(u @ bore > 0, np.sinc(length_m * u[:, 0] / lam) * np.sinc(height_m * (u @ elev) / lam), 0.0)


def test_each_element_hears_a_point_on_its_own_bistatic_path():
    """Delay within a sample and phase within 0.05 rad of the closed form, for elements along a 1.5 m array; the
    line moves during the ping, so each element hears the point where it is when the echo arrives (v·2R/c on).
    Each element's amplitude relative to element 0's is the membrane's pattern along its own direction,
    Γ(u_k)/Γ(u_0), within 1 % (the outer elements 4–6 % below the transmitter's direction; issue 53, item 6)."""
    sc = _point_scene()
    arr = se.ReceiverArray(tuple((0.75 - 0.1 * k, 0.0, 0.02 * (k % 3)) for k in range(16)))
    sonar = se.Sonar(frequency_hz=F0, length_m=0.05, height_m=0.02, tilt_deg=20, max_range_m=20, receive_array=arr)
    traj = se.Trajectory.line(start=(-0.2, 0, 5), end=(0.2, 0, 5), n_pings=2)
    rec = se.simulate(sc, traj, sonar, se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.3), speckle=True,
                      seed=0)
    compiled = sc.compiled(np.zeros(3))
    top = clutter_field(compiled, 0).points + compiled.origin_m
    fs = rec.sonar.sample_rate_hz
    checked = 0
    for p in range(len(traj)):
        tx = traj.positions_m[p]
        rx = arr.world_positions(traj.rotations()[p:p + 1], tx[None])[0, arr.n_elements:]  # starboard's
        r = np.linalg.norm(top - tx, axis=1)
        moved = rx[None] + traj.velocity_m_s[p] * (2.0 * r / C)[:, None, None]          # (points, elements, 3)
        tau = (r[:, None] + np.linalg.norm(top[:, None] - moved, axis=2)) / C
        for i in range(top.shape[0]):
            others = np.delete(tau, i, axis=0)
            if others.size and np.min(np.abs(others - tau[i])) < 6.0 / B:
                continue                                                    # another echo within its lobes
            z = rec.element_data[p, 1]                                      # (elements, samples)
            n = np.rint(tau[i] * fs).astype(int)
            peak = np.array([np.argmax(np.abs(z[k, n[k] - 8:n[k] + 9])) - 8 for k in range(arr.n_elements)])
            assert np.all(np.abs(peak) <= 1), peak                          # the delay within a sample
            at = np.array([_interpolate(z[k], tau[i, k] * fs) for k in range(arr.n_elements)])
            got = np.angle(at * np.conj(at[0]))
            want = np.angle(np.exp(-2j * np.pi * F0 * (tau[i] - tau[i, 0])))
            np.testing.assert_allclose(np.angle(np.exp(1j * (got - want))), 0.0, atol=0.05)
            u = (top[i] - rx) / np.linalg.norm(top[i] - rx, axis=1)[:, None]      # from each element, at the ping
            gamma = _membrane(u, 0.05, 0.02, 20.0)
            np.testing.assert_allclose(np.abs(at) / np.abs(at[0]), gamma / gamma[0], rtol=0.01)
            checked += 1
    assert checked >= 2


@pytest.mark.parametrize("label", ["seafloor", "strip"])
def test_off_line_elements_hear_the_lattice_through_their_own_elevation_pattern(label):
    """Four elements 0.1 m apart across the line of sight (so that their ranges to it differ by millimetres) hear a
    5 cm wide strip of seabed or an object's (the lattice's nodes, with speckle) 7.8 m out on the slope of a 10 cm
    tall membrane's elevation beam: each element's energy against element 0's within 0.6 dB of the closed form
    Σ Γ²(u_0)·Γ²(u_k)/(r_0²·r_k²) over the strip's centre line and the pings (the membrane, sinc·sinc), 2 to 8 dB
    down; with the transmitter's pattern for all (before issue 53, item 6) they were within 0.5 dB of element 0."""
    length, height, tilt = 0.2, 0.1, 35.0
    sc = se.Scene()
    strip = trimesh.Trimesh([[-1, -6.025, 0], [1, -6.025, 0], [1, -5.975, 0], [-1, -5.975, 0]], [[0, 1, 2], [0, 2, 3]])
    sc.add(strip, material=se.Material(backscatter_db=-10), label=label)
    dep = np.arctan2(5.0, 6.0)                                       # the strip's depression from the sonar
    arr = se.ReceiverArray(tuple((0.0, d * np.sin(dep), d * np.cos(dep)) for d in (0.0, 0.1, 0.2, 0.3)))
    sonar = se.Sonar(frequency_hz=F0, length_m=length, height_m=height, tilt_deg=tilt, max_range_m=12,
                     receive_array=arr)
    traj = se.Trajectory.line(start=(-0.1, 0, 5), end=(0.1, 0, 5), n_pings=3)
    pulse = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.3)
    energy = sum(np.sum(np.abs(se.simulate(sc, traj, sonar, pulse, speckle=True, seed=seed).element_data[:, 1]) ** 2,
                        axis=(0, 2)) for seed in range(6))
    x = np.linspace(-1, 1, 2001)
    line = np.stack([x, np.full_like(x, -6.0), np.zeros_like(x)], axis=1)
    want = np.zeros(arr.n_elements)
    for p in range(len(traj)):
        tx = traj.positions_m[p]
        rx = arr.world_positions(traj.rotations()[p:p + 1], tx[None])[0, arr.n_elements:]      # starboard's
        r0 = np.linalg.norm(line - tx, axis=1)
        g0 = _membrane((line - tx) / r0[:, None], length, height, tilt)
        for k in range(arr.n_elements):
            rk = np.linalg.norm(line - rx[k], axis=1)
            want[k] += np.sum(g0 ** 2 * _membrane((line - rx[k]) / rk[:, None], length, height, tilt) ** 2
                              / (r0 * rk) ** 2)
    got_db, want_db = 10 * np.log10(energy / energy[0]), 10 * np.log10(want / want[0])
    assert want_db[1] < -1.5 and want_db[3] < -7.5
    np.testing.assert_allclose(got_db, want_db, atol=0.6)


@pytest.mark.parametrize("surface", [None, 15.0], ids=["open", "sea_surface"])
def test_a_one_element_array_at_the_transmitter_is_the_side_scan_bit_for_bit(surface):
    """Also under a sea surface, whose paths put the element (or its image) on each leg."""
    sc, traj = _floor_scene(), se.Trajectory.line(start=(-1, 0, 8), end=(1, 0, 8), n_pings=3)
    env = se.Environment(surface=None if surface is None else se.SeaSurface(z_m=surface))
    plain = se.simulate(sc, traj, se.Acquisition(se.Sonar(max_range_m=20), env), speckle=True, seed=1,
                        keep_complex=True)
    one = se.simulate(sc, traj, se.Acquisition(se.Sonar(max_range_m=20, receive_array=se.ReceiverArray()), env),
                      speckle=True, seed=1)
    assert np.abs(plain.data).max() > 0
    assert np.array_equal(plain.data, one.data)
    assert np.array_equal(plain.complex_data, one.element_data[:, :, 0])


def test_speckle_is_coherent_across_elements():
    """Two elements at one place record the same bits; a small baseline keeps them coherent (|γ| near 1), while a
    second seed's scatterers are independent of the first's (|γ| near 0)."""
    sc, traj = _floor_scene(), se.Trajectory.line(start=(-1, 0, 8), end=(1, 0, 8), n_pings=4)
    arr = se.ReceiverArray(((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.002)))
    sonar = se.Sonar(max_range_m=20, receive_array=arr)
    rec = se.simulate(sc, traj, sonar, speckle=True, seed=1)
    other = se.simulate(sc, traj, sonar, speckle=True, seed=2)
    z = rec.element_data[:, 1]
    assert np.array_equal(z[:, 0], z[:, 1]) and np.abs(z).max() > 0
    band = (rec.slant_range_m > 10) & (rec.slant_range_m < 19)
    near = cross_spectrum(z[:, 0], z[:, 2], (1, 9))[1][:, band]
    apart = cross_spectrum(z[:, 0], other.element_data[:, 1, 0], (1, 9))[1][:, band]
    assert np.median(near) > 0.95 and np.median(apart) < 0.5


def test_element_data_survive_npz_and_zarr_with_an_element_dimension(tmp_path):
    sc, traj = _floor_scene(), se.Trajectory.line(start=(-1, 0, 8), end=(1, 0, 8), n_pings=2)
    sonar = se.Sonar(max_range_m=15, receive_array=se.ReceiverArray.vertical(0.01, 3))
    rec = se.simulate(sc, traj, sonar, speckle=True, seed=1)
    assert rec.element_data.shape == (2, 2, 3, rec.data.shape[2])
    np.testing.assert_allclose(np.abs(rec.element_data[:, :, 0]) ** 2, rec.data, rtol=1e-12)
    rec.save(tmp_path / "r.npz")
    assert np.array_equal(se.Record.load(tmp_path / "r.npz").element_data, rec.element_data)
    rec.to_zarr(tmp_path / "r.zarr")
    ds = xr.open_zarr(tmp_path / "r.zarr")
    assert ds["port_elements"].dims == ("ping", "element", "sample")
    np.testing.assert_array_equal(ds["element_up_m"].values, [0.0, 0.01, 0.02])
    back = se.Record.load(tmp_path / "r.zarr")
    assert back.sonar == rec.sonar and np.array_equal(np.asarray(back.element_data), rec.element_data)


def test_array_layouts_and_bad_values():
    arr = se.ReceiverArray.along_track(4, 0.05)
    np.testing.assert_allclose(np.asarray(arr.positions_m)[:, 0], [0.075, 0.025, -0.025, -0.075])
    np.testing.assert_allclose(arr.body_offsets(-1.0), arr.body_offsets(1.0))          # on the axis: no side
    tilted = se.ReceiverArray(((0.0, 0.1, 0.2),))
    np.testing.assert_allclose(tilted.body_offsets(-1.0), [[0.0, -0.1, -0.2]])          # port: outward is −y
    assert se.Sonar(receive_array={"positions_m": [[0, 0, 0], [0, 0, 0.01]]}).receive_array.n_elements == 2
    for bad, match in ((lambda: se.ReceiverArray(((0, 0),)), "triples"),
                       (lambda: se.ReceiverArray(((0, 0, 20.0),)), "within 10 m"),
                       (lambda: se.ReceiverArray(()), "1 to 256"),
                       (lambda: se.ReceiverArray.vertical(-0.1), "baseline_m"),
                       (lambda: se.ReceiverArray.along_track(0, 0.1), "n_elements"),
                       (lambda: se.Sonar(receive_array={"spacing": 1}), "unknown key 'spacing'"),
                       (lambda: se.Sonar(receive_array=3), "ReceiverArray")):
        with pytest.raises(ConfigError, match=match):
            bad()


@pytest.mark.parametrize("kwargs, match", [(dict(speckle=False), "speckle=True"),
                                           (dict(speckle=True, detection="incoherent"), "coherent"),
                                           (dict(speckle=True, lowpass_hz=5e3), "lowpass_hz")])
def test_an_array_without_coherent_speckle_is_refused(kwargs, match):
    sonar = se.Sonar(max_range_m=15, receive_array=se.ReceiverArray.vertical(0.01))
    with pytest.raises(ConfigError, match=match):
        se.simulate(_floor_scene(), se.Trajectory.line(start=(0, 0, 8), end=(1, 0, 8), n_pings=2), sonar, **kwargs)


def test_volume_reverberation_with_an_array_is_refused():
    sonar = se.Acquisition(se.Sonar(max_range_m=15, receive_array=se.ReceiverArray.vertical(0.01)),
                           se.Environment(volume_backscatter_db=-70))
    with pytest.raises(ConfigError, match="volume_backscatter_db"):
        se.simulate(_floor_scene(), se.Trajectory.line(start=(0, 0, 8), end=(1, 0, 8), n_pings=2), sonar,
                    speckle=True)


def test_a_toml_receive_array_renders_element_data(tmp_path):
    """``receive_array = {kind = …}`` in a config's [sonar]: the rendered record keeps its elements; bad tables are
    one-line errors naming the key."""
    cfg = tmp_path / "run.toml"
    cfg.write_text('[sonar]\nmax_range_m = 15.0\nreceive_array = { kind = "along_track", n_elements = 3, '
                   'spacing_m = 0.05 }\n[simulation]\nspeckle = true\n[trajectory]\nkind = "line"\n'
                   'start = [-1.0, 0.0, 8.0]\nend = [1.0, 0.0, 8.0]\nn_pings = 3\n[[objects]]\nseafloor = "flat"\n'
                   'size_m = [30.0, 40.0]\nlabel = "seafloor"\n[output]\nnpz = true\npng = false\n')
    assert main(["render", str(cfg), "-o", str(tmp_path / "out"), "--no-progress"]) == 0
    rec = se.Record.load(tmp_path / "out" / "record.npz")
    assert rec.element_data.shape[:3] == (3, 2, 3) and np.abs(rec.element_data).max() > 0
    assert rec.sonar.receive_array == se.ReceiverArray.along_track(3, 0.05)
    for table, match in (({"kind": "ring"}, "unknown kind 'ring'"),
                         ({"kind": "vertical", "baseline_m": 0.01, "spacing_m": 1}, "unknown key 'spacing_m'")):
        with pytest.raises(ConfigError, match=match):
            se.Sonar(receive_array=table)


def test_a_streamed_line_keeps_the_elements_bit_for_bit(tmp_path):
    """render_line in blocks of 2 pings: the store's element data are the one-call record's, bit for bit."""
    sc, traj = _floor_scene(), se.Trajectory.line(start=(-1, 0, 8), end=(1, 0, 8), n_pings=5)
    sonar = se.Sonar(max_range_m=15, receive_array=se.ReceiverArray.vertical(0.004))
    whole = se.simulate(sc, traj, sonar, speckle=True, seed=2)
    se.stream.render_line(sc, traj, tmp_path / "line.zarr", sonar, block_pings=2, speckle=True, seed=2)
    back = se.Record.load(tmp_path / "line.zarr")
    assert np.array_equal(np.asarray(back.element_data), whole.element_data)
    assert np.array_equal(np.asarray(back.data), whole.data)


def _cube_scene():
    """A 20 cm cube at 14.5 m across over a 6 m × 5 m floor patch, both on the lattice (no clutter points)."""
    sc = se.Scene()
    sc.add(trimesh.Trimesh([[-3, -17, 0], [3, -17, 0], [3, -12, 0], [-3, -12, 0]], [[0, 1, 2], [0, 2, 3]]),
           material=se.Material(backscatter_db=-27), label="floor")
    box = trimesh.creation.box((0.2, 0.2, 0.2))
    box.apply_translation((0.3, -14.5, 0.1))
    return sc.add(box, material=se.Material(backscatter_db=-10), label="cube")


def _sas_sonar(arr):
    return se.Sonar(frequency_hz=F0, length_m=0.04, height_m=0.02, tilt_deg=20, max_range_m=20, receive_array=arr)


def test_elements_from_one_emission_agree_with_each_element_synthesised_alone():
    """16 elements 4 cm apart share each node's scatterers, their fractional delays applied by FFT; each element
    alone (a one-element array at its place, the per-element splat) is the reference: at the cube's compressed peak
    within 0.01 dB and 0.01 rad, and the whole record within −40 dB of its energy (issue 53, item 4)."""
    arr = se.ReceiverArray.along_track(16, 0.04)
    traj = se.Trajectory.line(start=(-0.2, 0, 5), end=(0.2, 0, 5), n_pings=3)
    pulse = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.1)
    sc = _cube_scene()
    rec = se.simulate(sc, traj, _sas_sonar(arr), pulse, speckle=True, seed=3)
    for k in (0, 5, 10, 15):
        alone = se.simulate(sc, traj, _sas_sonar(se.ReceiverArray((arr.positions_m[k],))), pulse, speckle=True,
                            seed=3).element_data[:, :, 0]
        got = rec.element_data[:, :, k]
        peak = np.unravel_index(np.argmax(np.abs(alone)), alone.shape)
        assert abs(20 * np.log10(abs(got[peak]) / abs(alone[peak]))) < 0.01
        assert abs(np.angle(got[peak] / alone[peak])) < 0.01
        assert np.sum(np.abs(got - alone) ** 2) < 1e-4 * np.sum(np.abs(alone) ** 2)
        assert not np.array_equal(got, alone)                      # the shared path ran, not the splat


def test_shared_emission_keeps_its_bits_whatever_the_chunk_of_pings(monkeypatch):
    """The elements' sub-rows are filled a few pings at a time (synthesis.SHARED_BYTES): one ping per thread at a
    time gives the same bits as the whole block."""
    from sonar_embree import kernels
    from sonar_embree.signal import synthesis

    arr = se.ReceiverArray.along_track(4, 0.04)
    traj = se.Trajectory.line(start=(-0.3, 0, 5), end=(0.3, 0, 5), n_pings=7)
    pulse = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.1)
    whole = se.simulate(_cube_scene(), traj, _sas_sonar(arr), pulse, speckle=True, seed=3)
    monkeypatch.setattr(synthesis, "SHARED_BYTES", 1)
    assert synthesis.shared_chunk_pings(8, 1000) == kernels.num_threads()
    chunked = se.simulate(_cube_scene(), traj, _sas_sonar(arr), pulse, speckle=True, seed=3)
    assert np.abs(whole.element_data).max() > 0
    assert np.array_equal(whole.element_data, chunked.element_data)


def test_an_arrays_pings_reach_the_speckle_kernel_a_ping_per_thread(monkeypatch):
    """A receiver array's blocks hold a ping per thread (the kernels run a ping per thread): its first block was one
    ping, and later ones one ping too where a ping casts more than BLOCK_RAYS/2 rays (a SAS fan's 0.2° lines), which
    left every core but one idle (a 16-element ping cost 3.4 single channels on 2 cores; 1.9 since). The real
    kernel runs; the test only counts the pings of each call. Same bits as blocks of one ping."""
    import numba

    from sonar_embree import kernels

    if kernels.num_threads() < 2:
        pytest.skip("one Numba thread: every block is a ping per thread")
    seen, real = [], kernels.speckle_block_shared

    def counting(*args):
        seen.append(args[5].size)                         # status: one entry per ping of the call
        return real(*args)

    monkeypatch.setattr(kernels, "speckle_block_shared", counting)
    traj = se.Trajectory.line(start=(-0.3, 0, 5), end=(0.3, 0, 5), n_pings=4)
    pulse = se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.1)
    sonar = _sas_sonar(se.ReceiverArray.along_track(4, 0.04))
    rec = se.simulate(_cube_scene(), traj, sonar, pulse, speckle=True, seed=3)
    assert seen and min(seen) >= 2, seen
    n = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = se.simulate(_cube_scene(), traj, sonar, pulse, speckle=True, seed=3)
    finally:
        numba.set_num_threads(n)
    assert np.array_equal(rec.element_data, one.element_data)


def test_blocks_take_a_ping_per_thread_within_the_ray_budget(monkeypatch):
    """About BLOCK_RAYS rays a block, but a ping per thread while under MAX_BLOCK_RAYS, 1 to 64 pings, and never
    more than half the machine's memory holds (checks.BYTES_PER_RAY a ray)."""
    import importlib

    from sonar_embree import checks, kernels

    sim = importlib.import_module("sonar_embree.simulate")     # the package's `simulate` is the function
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: 2 ** 36)                     # a 64 GiB machine
    threads = kernels.num_threads()
    assert sim.next_block_pings(1) == 64
    assert sim.next_block_pings(sim.BLOCK_RAYS // 3) == max(3, min(threads, 64))
    assert sim.next_block_pings(sim.BLOCK_RAYS * 3) == max(1, min(threads, sim.MAX_BLOCK_RAYS // (sim.BLOCK_RAYS * 3)))
    assert sim.next_block_pings(sim.MAX_BLOCK_RAYS + 1) == 1
    monkeypatch.setattr(checks, "physical_memory_bytes", lambda: 3 * 1000 * checks.BYTES_PER_RAY)   # 1.5 pings
    assert sim.next_block_pings(1000) == 1


@pytest.mark.parametrize("array", [None, se.ReceiverArray.along_track(4, 0.04)], ids=["one receiver", "elements"])
def test_a_moving_receiver_hears_each_clutter_point_where_it_is_when_the_echo_arrives(array):
    """At 2 m/s along track, 3 m before a clutter point, the return leg is |X − p_k − v·τ0| (τ0 = 2R/c): the phase at
    the echo's time within 0.05 rad of that closed form for every receiver, where stop-and-hop is off by > 1 rad."""
    sc = _point_scene()
    sonar = se.Sonar(frequency_hz=F0, length_m=0.04, height_m=0.02, tilt_deg=20, max_range_m=20, receive_array=array)
    n, v = 3, np.array([2.0, 0.0, 0.0])
    pos = np.stack([np.linspace(-3.2, -2.8, n), np.zeros(n), np.full(n, 5.0)], axis=1)
    traj = se.Trajectory(pos, np.full(n, 90.0), np.zeros(n), np.zeros(n), np.arange(n) * 0.2,
                         velocity_m_s=np.tile(v, (n, 1)))
    rec = se.simulate(sc, traj, sonar, se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.3), speckle=True,
                      seed=0, keep_complex=True)
    compiled = sc.compiled(np.zeros(3))
    field = clutter_field(compiled, 0)
    top, fs = field.points + compiled.origin_m, rec.sonar.sample_rate_hz
    checked = 0
    for p in range(n):
        rx = pos[p][None] if array is None else array.world_positions(traj.rotations()[p:p + 1], pos[p][None])[
            0, array.n_elements:]                                                    # starboard's
        tau0 = 2.0 * np.linalg.norm(top - pos[p], axis=1) / C
        back = top[:, None] - rx[None] - v * tau0[:, None, None]                    # (points, receivers, 3)
        tau = (0.5 * C * tau0[:, None] + np.linalg.norm(back, axis=2)) / C
        z = rec.complex_data[p, 1][None] if array is None else rec.element_data[p, 1]
        for i in range(top.shape[0]):
            if np.min(np.abs(np.delete(tau[:, 0], i) - tau[i, 0]), initial=1.0) < 6.0 / B:
                continue                                                             # another echo within its lobes
            at = np.array([_interpolate(z[k], tau[i, k] * fs) for k in range(z.shape[0])])
            moving = np.angle(at * np.exp(-2j * np.pi * (field.phase[i] - F0 * tau[i])))
            stop = np.angle(at * np.exp(-2j * np.pi * (field.phase[i] - F0 * (tau0[i] + (tau[i] - tau[i, 0])))))
            assert np.abs(moving).max() < 0.05, moving
            assert np.abs(stop).min() > 1.0, stop
            checked += 1
    assert checked >= 2


def test_under_a_surface_an_element_off_the_transmitter_hears_both_one_bounce_paths():
    """Issue 53, item 6. S→X→S' and S'→X→S are one echo of twice the weight for the transmitter (docs/physics.md
    §13); an element R 0.6 m above it hears them on different legs, S→X→R' and S'→X→R, 0.72 m of path apart for a
    small cube 10 m out and 5 m down, 3 m under the surface. Over 8 pings 0.8 m apart (independent looks at the
    cube), each arrives at its own closed-form time (its centroid's delay after the direct echo's within 3 samples
    of the closed form's for the cube's centre, 19 samples apart; the faces each leg sees move it by a few cm) with half the one-bounce weight: the two arrivals' energies within a factor 2 of each other
    (each its own scatterer draw, so that they add in power as the transmitter's do). Before, the second was
    missing (its energy that of side lobes)."""
    z_s, x = 10.0, np.array([0.0, -10.0, 2.0])
    sc = se.Scene().add(trimesh.creation.box(extents=(0.2, 0.2, 0.2)).apply_translation(x),
                        material=se.Material(backscatter_db=-10), label="cube")
    arr = se.ReceiverArray(((0.0, 0.0, 0.0), (0.0, 0.0, 0.6)))
    sonar = se.Sonar(frequency_hz=F0, length_m=0.05, height_m=0.02, tilt_deg=20, max_range_m=25, receive_array=arr)
    traj = se.Trajectory.line(start=(-2.8, 0, 7.0), end=(2.8, 0, 7.0), n_pings=8)
    traj = dataclasses.replace(traj, velocity_m_s=None)                  # stop-and-hop: the closed form's legs
    rec = se.simulate(sc, traj, se.Acquisition(sonar, se.Environment(surface=se.SeaSurface(z_m=z_s))),
                      se.Pulse.lfm(bandwidth_hz=B, duration_s=1e-3, taper=0.3), speckle=True, seed=3)
    mirror = lambda p: p * [1, 1, -1] + [0, 0, 2 * z_s]
    d = lambda a, b: float(np.linalg.norm(a - b))
    fs = rec.sonar.sample_rate_hz
    energy = {"S-X-R'": 0.0, "S'-X-R": 0.0}
    for p, tx in enumerate(traj.positions_m):
        r1 = tx + [0.0, 0.0, 0.6]
        taus = {"direct": (d(x, tx) + d(x, r1)) / C, "S-X-R'": (d(x, tx) + d(x, mirror(r1))) / C,
                "S'-X-R": (d(x, mirror(tx)) + d(x, r1)) / C}
        assert abs(taus["S'-X-R"] - taus["S-X-R'"]) * C > 0.6
        z = np.abs(rec.element_data[p, 1, 1]) ** 2                       # starboard, the upper element
        peak = {}
        for name, tau in taus.items():
            n = int(round(tau * fs))
            part = z[n - 10:n + 11]
            peak[name] = n - 10 + float(np.sum(np.arange(21) * part) / part.sum())    # the arrival's centroid
            if name != "direct":
                energy[name] += part.sum()
        for name in energy:                                              # after the direct echo, as the closed form
            assert abs(peak[name] - peak["direct"] - (taus[name] - taus["direct"]) * fs) <= 3.0, (p, name, peak)
    assert 0.5 < energy["S'-X-R"] / energy["S-X-R'"] < 2.0, energy
