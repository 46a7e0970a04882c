"""Figure functions: decimation keeps the shape, PDFs are byte-stable, data drawn is right."""

import dataclasses

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from paper_repro import Config, make_scene
from paper_repro.plots import common as P
from paper_repro.plots.animation import animate_flight
from paper_repro.plots.distance import (
    plot_distance_slice,
    plot_eta_sigma,
    plot_gradient_field,
    plot_half_squared_limit,
    slice_grid,
    slice_through,
)
from paper_repro.plots.flight import (
    avoidance_window,
    lidar_instants,
    plot_flight_3d,
    plot_input_spectrum,
    plot_projection,
    plot_solve_times,
    plot_states,
    plot_thrusts,
    plot_tracking_errors,
    setup_label,
    view_window,
)
from paper_repro.plots.moving import (
    PREDICTION_COLOURS,
    animate_crossing,
    plot_clearance_time,
    plot_crossing_closest,
    plot_prediction_study,
    prediction_velocities,
)
from paper_repro.plots.sensing import (
    plot_scan_change_du,
    plot_scan_change_study,
    plot_scan_change_thrusts,
    plot_sensing_window,
    scan_change_times,
)
from paper_repro.sim.perception import ScanLog
from paper_repro.sim.result import SimulationResult
from paper_repro.world.lidar import Lidar


@pytest.fixture(scope="module")
def scene():
    return make_scene("paper")


@pytest.fixture(scope="module")
def result(scene):
    """A hand-made flight of the paper scene: from the start past the tower (1 m from its
    face at t = 30 s) to the first target, which is reached at step 4,000 of 6,000."""
    steps = 6000
    k = np.arange(steps + 1)
    waypoints = np.array([[22.0, -22.0, 0.0], [16.0, -12.5, 3.0], [-12.0, 18.0, 11.0],
                          [-15.0, 18.0, 5.0]])
    s = np.interp(k, [0, 3000, 4000, steps], [0, 1, 2, 3])
    x = np.zeros((steps + 1, 12))
    for i in range(3):
        x[:, i] = np.interp(s, np.arange(4), waypoints[:, i])
    u = 5.49 + 0.2 * np.sin(2 * np.pi * 0.2 * k[:-1] * 0.01)[:, None] * np.ones(4)
    u[3000:3100, 0] += 0.3 * (-1.0) ** np.arange(100)       # a burst of chattering
    targets = np.array([[-12.0, 18.0, 11.0], [-21.0, 18.0, 0.0]])
    index = (k[:-1] >= 4000).astype(int)
    lidar, scans = Lidar(scene.clouds, Config().sensor.range), ScanLog(len(scene.clouds), 3)
    for position in x[:-1, :3]:  # what a perfect LiDAR hands the controller on this path
        scans.add(lidar.scan(position))
    return SimulationResult(
        t=k[:-1] * 0.01, x=x, u=u, x_a=x[:-1], u_a=np.full((steps, 4), 5.49),
        solve_time=np.full(steps, 0.08), iterations=np.full(steps, 9),
        success=np.ones(steps, bool), status=np.full(steps, "Solve_Succeeded"),
        clearance=1.0 + np.abs(k[:-1] - 3000) / 1000, target_index=index,
        visible_points=np.zeros(steps, int), dropped_points=np.zeros(steps, int),
        targets=targets, reached=np.array([4000, -1]), outcome="step_limit", scene=scene,
        config=Config(), **scans.arrays())


def test_save_figure_is_byte_stable(tmp_path, result, scene):
    fig = plot_projection(result, scene, plane="xz")
    first = P.save_figure(fig, "a", tmp_path)
    second = P.save_figure(fig, "b", tmp_path)
    plt.close(fig)
    for p, q in zip(first, second):
        assert p.read_bytes() == q.read_bytes(), p.suffix
    pdf = first[0].read_bytes()
    assert pdf.startswith(b"%PDF") and b"CreationDate" not in pdf
    assert first[1].read_bytes().startswith(b"\x89PNG")


def test_save_figure_rejects_unknown_formats(tmp_path):
    fig = plt.figure()
    with pytest.raises(ValueError, match="format"):
        P.save_figure(fig, "x", tmp_path, formats=("svgz",))
    plt.close(fig)


def test_envelope_decimation_keeps_the_extremes_of_chattering():
    rng = np.random.default_rng(1)
    y = np.sin(np.linspace(0, 20, 135_000)) + 0.01 * rng.standard_normal(135_000)
    y[77_777] = 5.0
    idx = P.envelope_indices(y, 5000)
    assert len(idx) <= 5002
    assert idx[0] == 0 and idx[-1] == len(y) - 1 and np.all(np.diff(idx) > 0)
    assert y[idx].max() == y.max() and y[idx].min() == y.min()
    # Every bucket keeps its own min and max: the envelope is the original one.
    buckets = np.array_split(y, 50)
    dec = np.array_split(y[idx], 50)
    for b, d in zip(buckets, dec):
        assert d.max() == pytest.approx(b.max(), abs=0.05)
    assert np.array_equal(P.envelope_indices(y[:100], 5000), np.arange(100))


def test_stride_decimation_keeps_the_ends():
    idx = P.stride_indices(135_001, 5000)
    assert len(idx) <= 5000 and idx[0] == 0 and idx[-1] == 135_000
    assert np.array_equal(P.stride_indices(10, 5000), np.arange(10))


def _drawn_steps(result, line):
    """The steps a time-series line was drawn at (its x data are times of the run)."""
    t = np.asarray(line.get_xdata(), float)
    k = np.rint(t / result.config.nmpc.ts).astype(int)
    assert np.array_equal(result.t[k], t)  # every point is a logged instant, none invented
    return k


def test_paper_figures_draw_decimated_lines(result, scene):
    figs = {
        "3d": plot_flight_3d(result, scene, max_points=500),
        "xz": plot_projection(result, scene, "xz", max_points=500),
        "xy": plot_projection(result, scene, "xy", max_points=500),
        "thrusts": plot_thrusts(result, max_points=500),
        "errors": plot_tracking_errors(result, max_points=500),
        "states": plot_states(result, max_points=500),
        "solve": plot_solve_times([result], max_points=500),
    }
    assert len(figs["thrusts"].axes) == 4 and len(figs["states"].axes) == 3
    # Lines per axes: f_i, u_a,i and the target switch; e_x, e_y, e_z, the zero line and the
    # switch; x_I, x_a, x_t; trajectory, start and targets in a projection; one tail and T_s.
    per_axes = {"3d": [1], "xz": [3], "xy": [3], "thrusts": [3] * 4, "errors": [5],
                "states": [3] * 3, "solve": [2]}
    for name, fig in figs.items():
        assert [len(ax.get_lines()) for ax in fig.axes] == per_axes[name], name
        for ax in fig.axes:
            for line in ax.get_lines():
                assert len(line.get_xdata()) <= 502, name

    # What is drawn is the run's data, decimated, first and last step kept.
    pos = result.x[:, :3]
    traj = np.column_stack(figs["3d"].axes[0].get_lines()[0].get_data_3d())
    assert np.array_equal(traj, pos[P.stride_indices(len(pos), 500)])
    assert np.array_equal(traj[0], pos[0]) and np.array_equal(traj[-1], pos[-1])
    for plane, (i, j) in (("xz", (0, 2)), ("xy", (0, 1))):
        ax = figs[plane].axes[0]
        line = ax.get_lines()[0]
        assert np.array_equal(line.get_xdata(), pos[P.stride_indices(len(pos), 500), i])
        assert np.array_equal(line.get_ydata(), pos[P.stride_indices(len(pos), 500), j])
        assert (ax.get_xlabel(), ax.get_ylabel()) == (P.AXIS_LABELS[i], P.AXIS_LABELS[j])
        lo, hi = ax.get_xlim(), ax.get_ylim()  # the workspace holds the whole flight
        assert lo[0] <= pos[:, i].min() and pos[:, i].max() <= lo[1]
        assert hi[0] <= pos[:, j].min() and pos[:, j].max() <= hi[1]
    for i, ax in enumerate(figs["thrusts"].axes):
        f_i, u_a, switch = ax.get_lines()
        assert np.array_equal(switch.get_xdata(), [40.0, 40.0])  # target 1 reached at step 4,000
        k = _drawn_steps(result, f_i)
        assert np.array_equal(f_i.get_ydata(), result.u[k, i]) and k[0] == 0
        assert k[-1] == len(result.u) - 1
        assert np.array_equal(u_a.get_ydata(), result.u_a[_drawn_steps(result, u_a), i])
        assert ax.get_ylabel() == f"$f_{i + 1}$ [N]"
    assert figs["thrusts"].axes[-1].get_xlabel() == "t [s]"
    error = result.x[:-1, :3] - result.targets[result.target_index]
    for i, line in enumerate(figs["errors"].axes[0].get_lines()[:3]):
        assert np.allclose(line.get_ydata(), error[_drawn_steps(result, line), i])
    assert figs["errors"].axes[0].get_ylabel() == "error [m]"
    for i, ax in enumerate(figs["states"].axes):
        x_i, x_a, x_t = ax.get_lines()
        assert np.array_equal(x_i.get_ydata(), result.x[_drawn_steps(result, x_i), i])
        assert np.array_equal(x_a.get_ydata(), result.x_a[_drawn_steps(result, x_a), i])
        k = _drawn_steps(result, x_t)
        assert np.array_equal(x_t.get_ydata(), result.targets[result.target_index[k], i])
        assert ax.get_ylabel() == f"{'xyz'[i]} [m]"
    tail, ts = figs["solve"].axes[0].get_lines()  # share of steps at least this slow; T_s
    n = len(result.solve_time)
    assert np.allclose(tail.get_xdata(), 80.0) and tail.get_ydata()[0] == 1.0
    assert np.all(np.diff(tail.get_ydata()) < 0) and tail.get_ydata()[-1] == 1.0 / n
    assert np.array_equal(ts.get_xdata(), [10.0, 10.0])  # T_s = 10 ms
    for fig in figs.values():
        plt.close(fig)
    # The spectrum has one point per Welch bin: 512 above 0 Hz; the cut-off is marked.
    fig = plot_input_spectrum([result])
    spectrum, cutoff = fig.axes[0].get_lines()
    assert len(spectrum.get_xdata()) == 512 and np.all(spectrum.get_ydata() > 0)
    assert np.array_equal(cutoff.get_xdata(), [5.0, 5.0])
    assert fig.axes[0].get_xlabel() == "frequency [Hz]"
    plt.close(fig)


def test_thrust_figure_keeps_the_chattering_burst(result):
    fig = plot_thrusts(result, max_points=500)
    line = fig.axes[0].get_lines()[0]
    assert np.max(line.get_ydata()) == pytest.approx(result.u[:, 0].max())
    plt.close(fig)


def test_tracking_errors_are_against_the_active_target(result):
    # Signed by default, e_x = x_I − x_t as the paper's Figs. 5 and 7; |e| on request.
    for signed, f in ((True, lambda v: v), (False, abs)):
        fig = plot_tracking_errors(result, max_points=10**6, signed=signed)
        ex = fig.axes[0].get_lines()[0].get_ydata()
        assert ex[100] == pytest.approx(f(result.x[100, 0] - result.targets[0, 0]))
        assert ex[5000] == pytest.approx(f(result.x[5000, 0] - result.targets[1, 0]))
        ez = fig.axes[0].get_lines()[2].get_ydata()
        assert ez[100] == pytest.approx(f(result.x[100, 2] - result.targets[0, 2]))
        plt.close(fig)
    assert result.x[100, 2] < result.targets[0, 2]  # so e_z < 0 there: the sign is tested


def test_zoom_on_the_closest_approach(result):
    # Minimum clearance at step 3,000 (t = 30 s).
    assert avoidance_window(result) == pytest.approx((20.0, 40.0))
    assert avoidance_window(result, half_width=100.0) == pytest.approx((0.0, 59.99))
    fig = plot_thrusts(result, t_range=(20.0, 40.0))
    t = fig.axes[0].get_lines()[0].get_xdata()
    assert t.min() == pytest.approx(20.0) and t.max() == pytest.approx(40.0)
    assert np.max(fig.axes[0].get_lines()[0].get_ydata()) == pytest.approx(result.u[:, 0].max())
    plt.close(fig)
    for plot in (plot_states, plot_tracking_errors):
        fig = plot(result, t_range=(45.0, 50.0))
        assert all(45.0 <= x <= 50.0 for x in fig.axes[0].get_lines()[0].get_xdata())
        plt.close(fig)
    with pytest.raises(ValueError, match="t_range"):
        plot_thrusts(result, t_range=(100.0, 200.0))


def test_the_view_window_starts_before_the_first_point_in_view_and_titles_say_zoom(result):
    visible = np.zeros(result.steps, int)
    visible[2500:2600] = 7  # a point in view from t = 25 s
    seen = dataclasses.replace(result, visible_points=visible)
    assert view_window(seen) == pytest.approx((24.0, 44.0))
    assert view_window(seen, width=100.0) == pytest.approx((24.0, 59.99))  # clipped to the run
    assert view_window(result) == pytest.approx((0.0, 20.0))  # nothing seen: the start
    fig = plot_thrusts(seen, t_range=view_window(seen), full_range=True)
    lower, upper = seen.config.quadrotor.input_lower, seen.config.quadrotor.input_upper
    for ax, lo, hi in zip(fig.axes, lower, upper, strict=True):  # the whole box 𝒰, padded
        bottom, top = ax.get_ylim()
        assert bottom < lo < hi < top and top - bottom < 1.1 * (hi - lo)
    title = fig.axes[0].get_title()
    assert "zoom 24–44 s" in title and setup_label(seen) in title
    plt.close(fig)


def test_the_set_up_label_names_the_preset_and_its_horizon(result):
    from paper_repro.presets import preset

    assert setup_label(result).startswith("preset paper, the printed set-up, N = 35")
    timeline = dataclasses.replace(result, config=preset("paper-timeline", result.config))
    assert setup_label(timeline) == "preset paper-timeline, N = 43"
    tuned = dataclasses.replace(result, config=dataclasses.replace(
        result.config, barrier=dataclasses.replace(result.config.barrier, mu=1.0)))
    assert setup_label(tuned) == "N = 35"  # neither preset: only what is certain


def test_projection_rejects_unknown_plane(result, scene):
    with pytest.raises(ValueError, match="plane"):
        plot_projection(result, scene, plane="zz")


def test_lidar_instants_pick_the_closest_approach(result, scene):
    steps = lidar_instants(result, scene, n=3)
    assert len(steps) == 3 and steps == sorted(steps)
    # The flight passes the tower (region 0) within range: its closest approach is drawn.
    tower = scene.clouds[0]
    d = np.linalg.norm(result.x[:, None, :3] - tower[None], axis=2).min(axis=1)
    assert d.min() < 1.5 and int(np.argmin(d)) in steps
    pos = result.x[steps, :3]
    r_s = result.config.sensor.range
    assert all(np.linalg.norm(a - b) >= r_s for i, a in enumerate(pos) for b in pos[i + 1:])



@pytest.mark.parametrize("steps", [1, 2, 300, 3001])
def test_lidar_instants_of_a_cut_flight_index_its_steps(result, scene, steps):
    """A flight cut after any number of steps (a step limit, an interrupted run): every
    instant chosen indexes its per-step arrays, whose length is one less than x's."""
    cut = dataclasses.replace(result, x=result.x[:steps + 1], t=result.t[:steps],
                              u=result.u[:steps], visible_points=result.visible_points[:steps])
    chosen = lidar_instants(cut, scene, n=4)
    assert chosen and all(0 <= k < steps for k in chosen)
    assert [cut.t[k] for k in chosen] == sorted(cut.t[k] for k in chosen)

def test_a_saved_run_redraws_against_its_own_clouds(result, tmp_path):
    """The scene travels with the result: after save/load the figure's clouds are the
    flown ones, point for point, and the redrawn figure is the same picture, byte for byte."""
    result.save(tmp_path / "run")
    loaded = type(result).load(tmp_path / "run")
    assert loaded.scene.fingerprint() == result.scene.fingerprint()
    assert all(np.array_equal(a, b) for a, b in zip(loaded.scene.clouds, result.scene.clouds))
    fig = plot_projection(loaded, loaded.scene, plane="xy", max_points=200)
    drawn = [c.get_offsets() for c in fig.axes[0].collections]
    assert len(drawn) == len(result.scene.clouds)
    assert all(np.array_equal(d, c[:, :2]) for d, c in zip(drawn, result.scene.clouds))
    assert np.array_equal(fig.axes[0].get_lines()[0].get_xydata()[-1], result.x[-1, :2])
    before = plot_projection(result, result.scene, plane="xy", max_points=200)
    pngs = [P.save_figure(f, name, tmp_path, formats=("png",), dpi=40, close=True)[0]
            for f, name in ((before, "before"), (fig, "after"))]
    assert pngs[0].read_bytes() == pngs[1].read_bytes()


def test_slice_through_the_middle_of_a_cloud():
    cloud = np.array([[0.0, 0.0, 2.0], [4.0, 1.0, 6.0]])
    z, extent = slice_through(cloud, pad=1.0)
    assert z == 4.0 and extent == (-1.0, 5.0, -1.0, 2.0)


def test_tutorial_figures_and_bound(scene):
    from matplotlib.contour import ContourSet
    from matplotlib.quiver import Quiver

    cloud = scene.clouds[1]
    z, extent = slice_through(cloud)

    fig = plot_distance_slice(cloud, z, extent, 0.3, 0.8, n=30)
    smooth_ax, euclid_ax, colorbar = fig.axes
    assert colorbar.get_ylabel() == "m²" and "η = 0.3 m" in smooth_ax.get_title()
    levels = []
    for ax in (smooth_ax, euclid_ax):
        assert ax.get_xlim() == pytest.approx(extent[:2])
        assert ax.get_ylim() == pytest.approx(extent[2:])
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")
        filled, lines = [c for c in ax.collections if isinstance(c, ContourSet)]
        assert list(lines.levels) == [0.125, 0.5, 1.0, 2.0, 4.0, 8.0]  # the same in both
        levels.append(filled.levels[-1] - 1)  # the largest value on the slice
    assert levels[0] >= levels[1]  # D >= ½d² everywhere, so also its maximum
    plt.close(fig)

    fig = plot_eta_sigma(cloud, z, extent, n=25)
    assert [ax.get_title() for ax in fig.axes] == [
        "η = 0.1 m, σ = 0.8 m", "η = 0.3 m, σ = 0.8 m", "η = 0.6 m, σ = 0.8 m",
        "η = 0.3 m, σ = 0.8 m", "η = 0.3 m, σ = 2 m", "η = 0.3 m, σ = 100 m"]
    plt.close(fig)

    fig = plot_gradient_field(cloud, z, extent, 0.3, 0.8, n=8)
    _, _, q = slice_grid(extent, z, 8)
    nearest = cloud[np.argmin(((q[:, None] - cloud[None]) ** 2).sum(axis=2), axis=1)]
    expected = (q - nearest)[:, :2] / np.linalg.norm((q - nearest)[:, :2], axis=1)[:, None]
    for ax in fig.axes:
        (arrows,) = [c for c in ax.collections if isinstance(c, Quiver)]
        assert arrows.N == 64 and np.allclose(np.hypot(arrows.U, arrows.V), 1.0)
        assert np.allclose(np.column_stack([arrows.X, arrows.Y]), q[:, :2])
    euclid = [c for c in fig.axes[1].collections if isinstance(c, Quiver)][0]
    assert np.allclose(np.column_stack([euclid.U, euclid.V]), expected)  # away from a*
    plt.close(fig)

    # The bound drawn holds: max gap <= eta² max ln(V/W_j) at every eta, and the gap >= 0.
    fig = plot_half_squared_limit(cloud, z, extent, etas=[0.05, 0.3], n=15)
    worst, median, bound = fig.axes[0].get_lines()
    for line in (worst, median, bound):
        assert list(line.get_xdata()) == [0.05, 0.3]
    assert np.all(0 < median.get_ydata()) and np.all(median.get_ydata() <= worst.get_ydata())
    assert np.all(worst.get_ydata() <= bound.get_ydata())
    assert np.all(np.diff(worst.get_ydata()) > 0)  # vanishes as eta -> 0
    assert fig.axes[0].get_xlabel() == "η [m]" and "[m²]" in fig.axes[0].get_ylabel()
    plt.close(fig)


def test_animation_writes_a_gif_with_the_requested_frames(tmp_path, result, scene):
    from PIL import Image

    path = animate_flight(result, scene, tmp_path / "flight.gif", frames=3, dpi=30)
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 3
        assert im.size == (9 * 30, round(4.5 * 30))  # the 9 × 4.5 in figure at dpi 30
    with pytest.raises(ValueError, match="frames"):
        animate_flight(result, scene, tmp_path / "x.gif", frames=0)


@pytest.mark.parametrize("seconds, shown", [(0.08, "80 ms"), (6.7e-4, "0.67 ms")])
def test_solve_time_legend_shows_sub_millisecond_medians(result, seconds, shown):
    fast = dataclasses.replace(result, solve_time=np.full(len(result.solve_time), seconds))
    fig = plot_solve_times([fast])
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == [f"smooth (median {shown}, max {shown})", "$T_s$ = 10 ms"]
    # The tail: the share of steps at least as slow, 1 at the fastest step.
    tail = fig.axes[0].get_lines()[0].get_ydata()
    assert tail[0] == 1.0 and np.all(np.diff(tail) <= 0) and tail[-1] > 0
    plt.close(fig)


# --- the smooth sensing window ----------------------------------------------------------------

def test_sensing_window_figure_draws_psi_and_its_range_marks():
    from paper_repro.problem.distance import sensing_window

    fig = plot_sensing_window(3.0, widths=(0.25, 0.5, 1.0))
    lines = fig.axes[0].get_lines()
    cutoff = lines[0]
    r = cutoff.get_xdata()
    assert np.array_equal(cutoff.get_ydata(), (r < 3.0).astype(float))
    assert r.min() == pytest.approx(1.5) and r.max() > 3.0  # 1.5 w_max before r_s, and past
    for i, w in enumerate((0.25, 0.5, 1.0)):
        curve, marks = lines[1 + 2 * i], lines[2 + 2 * i]
        x, psi = curve.get_xdata(), curve.get_ydata()
        assert np.allclose(psi, np.exp(sensing_window(x, 3.0, w)))
        assert np.all(psi[x <= 3.0 - w] == 1.0) and np.all(psi[x >= 3.0] == 0.0)
        # full weight ends at r_s - w, half weight at r_s - w/2 (and psi is 1/2 there)
        assert np.allclose(marks.get_xdata(), [3.0 - w, 3.0 - w / 2])
        assert np.allclose(marks.get_ydata(), [1.0, 0.5])
        assert np.exp(sensing_window([3.0 - w / 2], 3.0, w))[0] == pytest.approx(0.5)
    plt.close(fig)
    for bad in ((), (0.0,), (3.0,)):
        with pytest.raises(ValueError, match="widths"):
            plot_sensing_window(3.0, widths=bad)


@pytest.fixture(scope="module")
def scan_result(result):
    """The hand-made flight with the visible set changing at steps 2000 (a smooth instant,
    |Δu| ≈ 2.5 mN), 2500 (every thrust steps by 50 mN) and 3050 (inside the chattering
    burst)."""
    visible = np.zeros(result.steps, int)
    visible[2000:] += 10
    visible[2500:] += 5
    visible[3050:] -= 3
    u = result.u.copy()
    u[2500:] += 0.05
    return dataclasses.replace(result, u=u, visible_points=visible)


def test_scan_change_times_are_the_steps_where_the_count_changes(scan_result):
    assert np.allclose(scan_change_times(scan_result), [20.0, 25.0, 30.5])


def test_scan_change_thrusts_mark_every_change_and_its_step(scan_result, result):
    fig = plot_scan_change_thrusts([scan_result, result], ["changes", "none"],
                                     t_range=(15.0, 35.0))
    axes = np.array(fig.axes).reshape(5, 2)
    for i in range(4):
        f = axes[i, 0].get_lines()[0]
        t = f.get_xdata()
        assert t.min() == pytest.approx(15.0) and t.max() == pytest.approx(35.0)
        assert np.allclose(f.get_ydata(), scan_result.u[1500:3501, i])
        marks = [ln.get_xdata()[0] for ln in axes[i, 0].get_lines()[1:]]
        assert np.allclose(marks, [20.0, 25.0, 30.5])
        assert len(axes[i, 1].get_lines()) == 1  # no change in the second run
        assert axes[i, 0].get_shared_y_axes().joined(axes[i, 0], axes[i, 1])
    du_line, dots, threshold = axes[4, 0].get_lines()[:3]
    du = np.abs(np.diff(scan_result.u, axis=0)).max(axis=1)
    assert np.allclose(du_line.get_ydata(), du[1499:3500])  # steps 1500..3500
    assert np.allclose(dots.get_xdata(), [20.0, 25.0, 30.5])
    assert np.allclose(dots.get_ydata(), du[[1999, 2499, 3049]])
    assert du[1999] < 0.01 < du[2499] and du[3049] > 0.01
    assert np.allclose(threshold.get_ydata(), 0.01) and axes[4, 0].get_yscale() == "log"
    assert "3 changes" in axes[0, 0].get_title() and "2 with a step" in axes[0, 0].get_title()
    assert "0 changes" in axes[0, 1].get_title()
    plt.close(fig)
    with pytest.raises(ValueError, match="label"):
        plot_scan_change_thrusts([result], ["a", "b"])


def test_scan_change_du_draws_the_ecdfs_at_and_around_the_changes(scan_result):
    from paper_repro.analysis.metrics import scan_change_steps

    for neighbourhood in (20, None):
        fig = plot_scan_change_du([scan_result], ["run"], neighbourhood=neighbourhood)
        ax = fig.axes[0]
        at_line, around_line, threshold = ax.get_lines()
        at, around = scan_change_steps(scan_result, neighbourhood)
        assert len(at) == 3 and len(around) == (120 if neighbourhood else scan_result.steps - 4)
        for line, values in ((at_line, at), (around_line, around)):
            assert np.allclose(line.get_xdata(), np.sort(np.maximum(values, 1e-7)))
            assert line.get_ydata()[-1] == pytest.approx(1.0)
        assert np.allclose(threshold.get_xdata(), 0.01) and ax.get_xscale() == "log"
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert labels[0] == "run, at changes (3 steps)"
        assert labels[1] == ("run, within 0.2 s around (120 steps)" if neighbourhood
                             else f"run, elsewhere ({scan_result.steps - 4} steps)")
        plt.close(fig)


def test_scan_change_study_draws_each_width():
    import pandas as pd
    from matplotlib.collections import LineCollection, PathCollection

    rows = []
    for w, share, step in ((0.0, 0.4, 3e-3), (0.5, 0.05, 1e-4)):
        for seed in range(3):
            rows.append({"window_m": w, "scene_seed": seed, "status": "ok",
                         "outcome": "completed" if seed else "stalled", "completed": seed > 0,
                         "stalled": seed == 0, "collision": False,
                         "scan_change_jump_share": share + 0.01 * seed,
                         "du_scan_change_median_N": step * (1 + seed),
                         "du_around_changes_median_N": 1e-4 * (1 + seed),
                         "min_clearance_m": 1.3 + w / 10 + 0.01 * seed})
    rows[1]["scan_change_jump_share"] = np.nan  # a run without a change of the visible set
    rows[1]["du_scan_change_median_N"] = rows[1]["du_around_changes_median_N"] = np.nan
    fig = plot_scan_change_study(pd.DataFrame(rows))
    rates, shares, steps, clearance = fig.axes
    heights = [p.get_height() for p in rates.patches]
    assert np.allclose(heights, [2 / 3, 1 / 3, 0.0] * 2)  # completed, stalled, collision
    def runs(ax):  # the per-run dots of a panel, one collection per width (and column)
        return [c for c in ax.collections if isinstance(c, PathCollection)]

    drawn = np.concatenate([c.get_offsets()[:, 1] for c in runs(shares)])
    assert np.allclose(np.sort(drawn), [0.05, 0.06, 0.07, 0.4, 0.42])
    assert "1 run(s) without a change" in [t.get_text() for t in shares.texts]
    assert steps.get_yscale() == "log" and len(runs(steps)) == 4  # at, around per width
    medians = [seg[0][1] for c in clearance.collections if isinstance(c, LineCollection)
               for seg in c.get_segments()]
    assert np.allclose(medians, [1.31, 1.36])
    plt.close(fig)
    empty = pd.DataFrame(rows).assign(scan_change_jump_share=np.nan)
    fig = plot_scan_change_study(empty)
    assert "no change of the visible set" in [t.get_text() for t in fig.axes[1].texts]
    plt.close(fig)


# --- moving obstacles -------------------------------------------------------------------------

class _HoverRecorder:
    """A stand-in controller that always hovers and records the velocities it is given."""

    def __init__(self, config, horizon: int = 5):
        from paper_repro.vehicles.quadrotor import equilibrium

        _, self.u_hover = equilibrium(np.zeros(3), 0.0, config.quadrotor)
        self.horizon = horizon
        self.velocities = []

    def reset(self):
        self.velocities = []

    def hover_guess(self, x0):
        from paper_repro.problem.ocp import NMPCSolution

        x0 = np.asarray(x0, float)
        return NMPCSolution(np.tile(self.u_hover, (self.horizon, 1)),
                            np.tile(x0, (self.horizon + 1, 1)), x0.copy(),
                            np.asarray(self.u_hover, float).copy(), True, "hover", 1, 1e-4, 0.0)

    def solve(self, x0, target, visible, previous=None, velocities=None):
        self.velocities.append(None if velocities is None else np.array(velocities))
        return self.hover_guess(x0)


def _approach_scene():
    """A 2 m box 5 m ahead of a hovering UAV, coming at it at 1 m/s along −x, then turning
    to +y at t = 2.5 s (so an estimate must follow a change of velocity)."""
    from paper_repro.world.motion import Motion
    from paper_repro.world.scene import Region, Scene
    from paper_repro.world.shapes import Box

    box = Region("incoming", Box((5.5, 0.0, 5.0), (2.0, 2.0, 2.0)), density=4.0)
    motion = Motion((0.0, 2.5, 3.5), ((0.0, 0.0, 0.0), (-2.5, 0.0, 0.0), (-2.5, 1.0, 0.0)))
    return Scene("approach", (box,), (0.0, 0.0, 5.0), ((-10.0, 0.0, 5.0),), 3,
                 motions=(motion,))


def _fly_approach(prediction, sensor=None, steps=350):
    from paper_repro.config import NMPCParams, SensorParams
    from paper_repro.sim.loop import simulate

    config = Config(nmpc=NMPCParams(prediction=prediction),
                    sensor=sensor or SensorParams())
    ctl = _HoverRecorder(config)
    result = simulate(config, ctl, max_steps=steps, scene=_approach_scene(), progress=False)
    return result, ctl.velocities


@pytest.fixture(scope="module")
def approach():
    return {p: _fly_approach(p) for p in ("static", "oracle", "kalman")}


def test_prediction_velocities_are_what_the_controller_was_given(approach, tmp_path):
    """The closed loop logs the velocities it hands the controller; a figure reads them from
    the saved result and never flies again."""
    from paper_repro.config import SensorParams
    from paper_repro.sim.result import SimulationResult

    result, given = approach["static"]
    assert all(v is None for v in given)
    assert np.array_equal(prediction_velocities(result), np.zeros((result.steps, 1, 3)))
    result, given = approach["oracle"]
    v = prediction_velocities(result)
    assert v.shape == (result.steps, 1, 3) and np.array_equal(v, np.array(given))
    np.testing.assert_array_equal(v[100, 0], (-1.0, 0.0, 0.0))
    np.testing.assert_array_equal(v[300, 0], (0.0, 1.0, 0.0))
    noisy = _fly_approach("kalman", SensorParams(range_noise=0.05, dropout=0.2,
                                                 spurious_rate=2.0, seed=4))
    for result, given in (approach["kalman"], noisy):
        v = prediction_velocities(result)
        assert np.array_equal(v, np.array(given))  # bit for bit, noise included
        saved = SimulationResult.load(result.save(tmp_path / "run"))
        assert np.array_equal(prediction_velocities(saved), v)
    result = approach["kalman"][0]
    v = prediction_velocities(result)
    seen = np.flatnonzero(result.visible_points > 0)
    assert seen[0] > 0 and np.all(v[: seen[0]] == 0)  # nothing estimated before first sight
    assert np.linalg.norm(v[240, 0] - (-1.0, 0.0, 0.0)) < 0.2  # tracked before the turn


def test_clearance_time_draws_each_run_with_its_minimum(approach):
    results = [approach[p][0] for p in ("static", "oracle")]
    fig = plot_clearance_time(results, ["static", "oracle"], t_range=(1.0, 3.0))
    ax = fig.axes[0]
    lines = ax.get_lines()
    k = np.flatnonzero((results[0].t >= 1.0) & (results[0].t <= 3.0))
    for i, r in enumerate(results):
        line, dot = lines[2 * i], lines[2 * i + 1]
        assert np.allclose(line.get_xdata(), r.t[k]) and np.allclose(line.get_ydata(),
                                                                      r.clearance[k])
        j = k[np.argmin(r.clearance[k])]
        assert dot.get_xdata()[0] == pytest.approx(r.t[j])
        assert dot.get_ydata()[0] == pytest.approx(r.clearance[j])
    assert lines[0].get_color() == PREDICTION_COLOURS["static"]
    assert np.allclose(lines[-1].get_ydata(), 0.35)
    text = [t.get_text() for t in ax.get_legend().get_texts()]
    j = k[np.argmin(results[0].clearance[k])]
    assert text[0] == f"static: min {results[0].clearance[j]:.3f} m at {results[0].t[j]:.2f} s"
    plt.close(fig)
    with pytest.raises(ValueError, match="label"):
        plot_clearance_time(results, ["one"])


def test_crossing_closest_draws_the_closest_approach_and_the_predicted_points(approach):
    from paper_repro.world.lidar import Lidar

    results = [approach[p][0] for p in ("static", "oracle", "kalman")]
    velocities = [None] + [prediction_velocities(r) for r in results[1:]]
    fig = plot_crossing_closest(results, ["static", "oracle", "kalman"],
                                  velocities=velocities, planes=("xy", "yz"))
    axes = np.array(fig.axes).reshape(2, 3)
    h = results[0].config.nmpc.prediction_step
    for col, (r, vel) in enumerate(zip(results, velocities, strict=True)):
        k = int(np.argmin(r.clearance))
        clouds = r.scene.clouds_at(r.t[k])
        seen = Lidar(clouds, 3.0).scan(r.x[k, :3])[0]
        for row, idx in enumerate(([0, 1], [1, 2])):
            ax = axes[row, col]
            cloud, in_view, *ghosts = ax.collections
            assert np.allclose(cloud.get_offsets(), clouds[0][:, idx])
            assert np.allclose(in_view.get_offsets(), seen[:, idx])
            if vel is None:
                assert ghosts == []
            else:
                assert len(ghosts) == 3
                for ghost, j in zip(ghosts, (0, 17, 35), strict=True):
                    assert np.allclose(ghost.get_offsets(), (seen + vel[k, 0] * j * h)[:, idx])
            segment = ax.get_lines()[-1]  # UAV to the nearest point: the clearance
            ends = np.c_[segment.get_xdata(), segment.get_ydata()]
            assert np.allclose(ends[0], r.x[k, idx])
            assert f"min clearance {r.clearance[k]:.3f} m" in ax.get_title()
            assert ax.get_xlim() == axes[row, 0].get_xlim()  # shared limits
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[-1] == "predicted at τ = 0, 0.17, 0.35 s"
    plt.close(fig)
    with pytest.raises(ValueError, match="one entry per run"):
        plot_crossing_closest(results, ["a", "b", "c"], velocities=[None])
    with pytest.raises(ValueError, match="plane"):
        plot_crossing_closest(results[:1], ["a"], planes=("xw",))


def test_animate_crossing_writes_a_gif_of_the_requested_frames(approach, tmp_path):
    from PIL import Image

    result = approach["kalman"][0]
    path = animate_crossing(result, tmp_path / "crossing.gif", frames=4, dpi=20,
                              t_range=(1.0, 3.0))
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 4
        assert im.size == (2 * 90, 90)  # two 4.5 × 4.5 in panels at dpi 20
    with pytest.raises(ValueError, match="frames"):
        animate_crossing(result, tmp_path / "x.gif", frames=0)
    with pytest.raises(ValueError, match="velocities"):
        animate_crossing(result, tmp_path / "x.gif", velocities=np.zeros((3, 1, 3)))


def test_prediction_study_draws_rates_and_runs_per_prediction_and_metric():
    import pandas as pd
    from matplotlib.collections import LineCollection, PathCollection

    rows = []
    for p, clear in (("static", 0.2), ("oracle", 0.6), ("kalman", 0.5)):
        for m in ("smooth", "euclidean"):
            for seed in range(4):
                hit = p == "static" and seed < 2
                rows.append({"prediction": p, "metric": m, "scene_seed": seed, "status": "ok",
                             "outcome": "completed" if seed else "stalled",
                             "completed": seed > 0, "stalled": seed == 0, "collision": hit,
                             "min_clearance_m": clear + 0.1 * seed,
                             "tv_u_rate_N_per_s": (2.0 if m == "smooth" else 500.0) + seed})
    fig = plot_prediction_study(pd.DataFrame(rows))
    # No run hit the step limit: no empty panel for it, and the title says so.
    completed, collided, stalled, clearance, tv = fig.axes
    assert fig.get_suptitle() == "no run of any group ended step limit"
    assert [ax.get_title() for ax in (completed, collided, stalled)] == [
        "completed rate", "collision rate", "stalled rate"]
    assert [t.get_text() for t in collided.get_xticklabels()] == ["static", "oracle", "kalman"]
    heights = [b.get_height() for b in collided.patches]  # smooth then euclidean, per prediction
    assert np.allclose(heights, [0.5, 0.0, 0.0] * 2)
    assert np.allclose([b.get_height() for b in completed.patches], 0.75)
    assert np.allclose([b.get_height() for b in stalled.patches], 0.25)
    dots = [c for c in clearance.collections if isinstance(c, PathCollection)]
    assert len(dots) == 6 and all(len(c.get_offsets()) == 4 for c in dots)
    medians = sorted(seg[0][1] for c in clearance.collections if isinstance(c, LineCollection)
                     for seg in c.get_segments())
    assert np.allclose(medians, [0.35, 0.35, 0.65, 0.65, 0.75, 0.75])
    assert tv.get_yscale() == "log"
    plt.close(fig)


def test_the_sweep_figure_shows_completion_and_collision_on_the_whole_share_axis():
    import pandas as pd

    from paper_repro.plots.studies import plot_sweep

    rows = [{"metric": "euclidean", "eta": 0.0, "sigma": np.nan}]
    rows += [{"metric": "smooth", "eta": eta, "sigma": 0.8} for eta in (0.1, 0.3, 0.8)]
    table = pd.DataFrame(rows)
    for col in ("tv_u_rate_N_per_s", "hf_energy_fraction", "min_clearance_m",
                "time_to_complete_s", "max_abs_du_N"):
        table[col] = [100.0, 50.0, 5.0, 1.0]
    for event, values in (("completed", [0.5, 0.6, 0.95, 0.75]),
                          ("stalled", [0.1, 0.2, 0.0, 0.0]),
                          ("collision", [0.0, 0.0, 0.0, 0.25])):
        table[f"{event}_rate"] = values
        table[f"{event}_low"], table[f"{event}_high"] = table[f"{event}_rate"] - 0.1, 1.0
    fig = plot_sweep(table, "eta", fixed={"sigma": 0.8})
    shown = {ax.get_title(): ax for ax in fig.axes if ax.get_visible()}
    assert len(shown) == 8
    collision = shown["collision rate (clearance < 0.35 m)"]
    assert np.allclose(collision.get_lines()[0].get_ydata(), [0.0, 0.0, 0.25])  # η = 0.1 .. 0.8
    assert collision.get_ylim() == pytest.approx((-0.05, 1.05))
    assert np.allclose(shown["completion rate"].get_lines()[0].get_ydata(), [0.6, 0.95, 0.75])
    plt.close(fig)
