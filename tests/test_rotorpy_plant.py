"""RotorPy as our plant: with every effect off it flies as our plant does; motor lag, mismatch
and wind do what they say; bad input and a missing rotorpy are named."""

import subprocess
import sys

import numpy as np
import pytest

from paper_repro.config import PlantParams, QuadrotorParams
from paper_repro.sim.plant import QuadrotorPlant
from paper_repro.sim.rotorpy_plant import RotorpyPlant
from paper_repro.vehicles.quadrotor import equilibrium
from paper_repro.world.wind import OneCosineGust, Wind


def effects(**settings) -> PlantParams:
    """RotorPy's plant with these settings (the effects need it)."""
    return PlantParams(simulator="rotorpy", **settings)


TS = 0.01
PARAMS = QuadrotorParams()
HOVER = PARAMS.hover_thrust


@pytest.fixture
def rotorpy():
    """rotorpy's Multirotor module; the test is skipped without rotorpy."""
    return pytest.importorskip("rotorpy.vehicles.multirotor",
                               reason='no rotorpy: pip install -e ".[hardware]"')


def fly(plant, x0, inputs) -> np.ndarray:
    """(len(inputs) + 1, 12) states of ``plant`` from x0 under the (n, 4) thrusts, N."""
    if hasattr(plant, "reset"):
        plant.reset(x0)
    xs = [np.asarray(x0, float)]
    for u in inputs:
        xs.append(plant.step(xs[-1], u))
    return np.array(xs)


def varied_thrusts(seconds: float) -> np.ndarray:
    """(n, 4) N: hover plus a collective, roll, pitch and yaw sequence of several frequencies."""
    t = np.arange(round(seconds / TS)) * TS
    roll = 0.02 * np.sin(2 * np.pi * 1.5 * t)
    pitch = 0.03 * np.cos(2 * np.pi * 1.1 * t + 0.3)
    yaw = 0.2 * np.sign(np.sin(2 * np.pi * 0.8 * t))
    collective = 0.5 * np.sin(2 * np.pi * 0.7 * t)
    return np.column_stack([HOVER + collective - pitch + yaw, HOVER + collective + roll - yaw,
                            HOVER + collective + pitch + yaw, HOVER + collective - roll - yaw])


def stabilising_law(x, target) -> np.ndarray:
    """(4,) N: a cascaded PD law (position to roll and pitch, attitude to torques) that flies
    the quadrotor of Table I to ``target`` (3,) m at yaw 0."""
    pos, ang, vel, rate = x[0:3], x[3:6], x[6:9], x[9:12]
    acc = 1.5 * (target - pos) - 2.0 * vel
    thrust = PARAMS.mass * (PARAMS.gravity + acc[2]) / (np.cos(ang[0]) * np.cos(ang[1]))
    theta_ref = np.clip(acc[0] / PARAMS.gravity, -0.3, 0.3)
    phi_ref = np.clip(-acc[1] / PARAMS.gravity, -0.3, 0.3)
    tau = np.array(PARAMS.inertia) * (
        40 * (np.array([phi_ref, theta_ref, 0.0]) - ang) - 12 * rate)
    h, k = PARAMS.arm, PARAMS.yaw_torque_ratio
    # Invert thrust = Σf, τx = h(f2 − f4), τy = h(f3 − f1), τz = k(f1 − f2 + f3 − f4).
    mix = np.array([[1, 1, 1, 1], [0, h, 0, -h], [-h, 0, h, 0], [k, -k, k, -k]])
    return np.linalg.solve(mix, np.concatenate([[thrust], tau]))


def test_hover_stays_at_hover(rotorpy):
    x0, u0 = equilibrium([1.0, -2.0, 3.0], yaw=0.7)
    plant = RotorpyPlant(PARAMS, TS)
    xs = fly(plant, x0, [u0] * 200)
    assert np.abs(xs - x0).max() < 1e-9
    assert plant.time == pytest.approx(2.0)
    assert plant.rotor_thrusts == pytest.approx(np.full(4, HOVER), rel=1e-12)


def test_effects_off_it_flies_our_plant_open_loop(rotorpy):
    """4 s of varied thrusts from a state with yaw near π and non-zero rates: the vehicle moves
    metres and turns through ψ = π (the angles stay unwrapped), and both plants agree to far
    below 1 cm."""
    x0 = np.zeros(12)
    x0[:3], x0[3:6], x0[6:9], x0[9:12] = [1, 2, 3], [0.05, -0.03, 3.0], [0.5, 0, 0], [0.1, 0, 0.4]
    inputs = varied_thrusts(4.0)
    ours = fly(QuadrotorPlant(PARAMS, TS), x0, inputs)
    theirs = fly(RotorpyPlant(PARAMS, TS), x0, inputs)
    assert np.linalg.norm(ours[-1, :3] - x0[:3]) > 1.0 and ours[:, 5].max() > np.pi
    assert np.abs(ours[:, :3] - theirs[:, :3]).max() < 1e-6
    assert np.abs(ours - theirs).max() < 1e-6


def test_effects_off_it_flies_our_plant_closed_loop(rotorpy):
    """5 s of a PD law flying 2 m sideways and 1 m up, each plant in its own loop."""
    target = np.array([2.0, -1.0, 1.0])
    paths = []
    for plant in (QuadrotorPlant(PARAMS, TS), RotorpyPlant(PARAMS, TS)):
        x = np.zeros(12)
        if hasattr(plant, "reset"):
            plant.reset(x)
        path = [x]
        for _ in range(500):
            x = plant.step(x, stabilising_law(x, target))
            path.append(x)
        paths.append(np.array(path))
    ours, theirs = paths
    assert np.linalg.norm(ours[-1, :3] - target) < 0.1  # the law does fly there
    assert np.abs(ours[:, :3] - theirs[:, :3]).max() < 1e-6


def test_rotor_speeds_persist_between_steps(rotorpy):
    """With a lag, two steps of T_s land where one step of 2·T_s does (to the integrator's
    tolerance, tightened here), and reset restarts."""
    lag, tight = effects(motor_lag=0.03), {"rtol": 1e-10, "atol": 1e-12}
    short, long = (RotorpyPlant(PARAMS, TS, lag, **tight),
                   RotorpyPlant(PARAMS, 2 * TS, lag, **tight))
    x0, u = np.zeros(12), np.full(4, 1.2 * HOVER)
    a = fly(short, x0, [u, u])[-1]
    b = fly(long, x0, [u])[-1]
    assert np.abs(a - b).max() < 1e-9
    assert short.rotor_speeds == pytest.approx(long.rotor_speeds, rel=1e-9)
    assert short.rotor_speeds[0] > long.commanded_speeds(np.full(4, HOVER))[0]
    short.reset(x0)
    assert short.time == 0 and short.rotor_thrusts == pytest.approx(np.full(4, HOVER))


def test_motor_lag_is_a_first_order_lag_of_tau(rotorpy):
    """A step of +10 % thrust: the rotor speeds follow ω_c + (ω_0 − ω_c)·e^{−t/τ} (RotorPy lags
    the speeds), the fitted time constant is τ, and the thrust reaches 63 % of its step at τ
    (within 2 %: thrust is k·ω², first-order only for small steps). Without a lag the thrust
    steps at once."""
    tau, dt = 0.03, 0.001
    plant = RotorpyPlant(PARAMS, dt, effects(motor_lag=tau))
    u = np.full(4, 1.1 * HOVER)
    x = np.zeros(12)
    plant.reset(x)
    w0, wc = plant.rotor_speeds[0], plant.commanded_speeds(u)[0]
    t, w, f = [], [], []
    for _ in range(120):
        x = plant.step(x, u)
        t.append(plant.time)
        w.append(plant.rotor_speeds[0])
        f.append(plant.rotor_thrusts[0])
    t, w, f = np.array(t), np.array(w), np.array(f)
    assert w == pytest.approx(wc + (w0 - wc) * np.exp(-t / tau), abs=1e-6)
    slope = np.polyfit(t, np.log((wc - w) / (wc - w0)), 1)[0]
    assert -1 / slope == pytest.approx(tau, rel=1e-4)
    reached = np.interp(1 - np.exp(-1), (f - HOVER) / (0.1 * HOVER), t)  # f rises monotonically
    assert reached == pytest.approx(tau, rel=0.02)
    instant = RotorpyPlant(PARAMS, dt)
    fly(instant, np.zeros(12), [u])
    assert instant.rotor_thrusts == pytest.approx(u, rel=1e-12)


def test_mismatch_of_thrust_mass_and_centre_of_mass(rotorpy):
    """Hover thrusts on a mismatched vehicle: z = ½·a·t² with a = g·(thrust_scale/mass_scale − 1);
    a centre of mass c ahead on x_b pitches the vehicle at θ̈ = 4·c·f/I_yy, towards it."""
    x0, u0 = equilibrium([0.0, 0.0, 5.0])
    t = 1.0
    for thrust_scale, mass_scale in ((1.1, 1.0), (0.9, 1.0), (1.0, 1.1)):
        mismatch = effects(thrust_scale=thrust_scale, mass_scale=mass_scale)
        x = fly(RotorpyPlant(PARAMS, TS, mismatch), x0, [u0] * round(t / TS))[-1]
        a = PARAMS.gravity * (thrust_scale / mass_scale - 1)
        assert x[2] - 5.0 == pytest.approx(0.5 * a * t**2, rel=1e-6)
    c, t = 0.02, 0.1
    x = fly(RotorpyPlant(PARAMS, TS, effects(com_offset=(c, 0.0, 0.0))), x0,
            [u0] * round(t / TS))[-1]
    assert x[4] == pytest.approx(0.5 * 4 * c * HOVER / PARAMS.inertia[1] * t**2, rel=0.01)
    assert abs(x[3]) < 1e-12


def test_wind_drifts_the_vehicle_downwind(rotorpy):
    """With drag on, a mean wind along (1, 1, 0) pushes a hovering vehicle along it, at the
    parasitic drag's initial acceleration c_D·|w|·w/m; still air does not move it."""
    drag = effects(parasitic_drag=(0.05, 0.05, 0.05))
    x0, u0 = equilibrium([0.0, 0.0, 5.0])
    wind = np.array([3.0, 3.0, 0.0]) / np.sqrt(2)
    x = fly(RotorpyPlant(PARAMS, TS, drag, wind=Wind(mean=wind)), x0, [u0] * 100)[-1]
    drift = x[:3] - x0[:3]
    assert drift @ wind / (np.linalg.norm(drift) * 3.0) > 0.9999
    a0 = 0.05 * 3.0 * 3.0 / PARAMS.mass
    assert 0.9 * 0.5 * a0 < np.linalg.norm(drift) < 0.5 * a0  # drag falls as it picks up speed
    still = fly(RotorpyPlant(PARAMS, TS, drag), x0, [u0] * 100)[-1]
    assert np.abs(still - x0).max() < 1e-9


def test_the_wind_is_read_at_each_sampling_instant(rotorpy):
    asked = []

    def wind(t):
        asked.append(t)
        return np.zeros(3)

    plant = RotorpyPlant(PARAMS, TS, effects(rotor_drag=1e-4), wind=wind)
    fly(plant, np.zeros(12), [np.full(4, HOVER)] * 5)
    assert asked == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    gust = OneCosineGust((0.0, 3.0, 0.0), duration=0.5, start=0.2)
    x = fly(RotorpyPlant(PARAMS, TS, effects(rotor_drag=1e-4), wind=gust),
            np.zeros(12), [np.full(4, HOVER)] * 40)
    assert np.abs(x[:21, :3]).max() < 1e-12  # nothing before the gust at 0.2 s
    assert x[-1, 1] > 1e-4 and abs(x[-1, 0]) < 1e-12  # then a push along it


def test_the_plant_leaves_numpys_global_generator_alone(rotorpy):
    np.random.seed(3)  # noqa: NPY002 - the legacy generator is what RotorPy draws from
    expected = np.random.rand()  # noqa: NPY002
    np.random.seed(3)  # noqa: NPY002
    fly(RotorpyPlant(PARAMS, TS), np.zeros(12), [np.full(4, HOVER)] * 3)
    assert np.random.rand() == expected  # noqa: NPY002


def test_wind_without_an_aerodynamic_effect_warns(rotorpy):
    with pytest.warns(UserWarning, match="wind acts only through an aerodynamic effect"):
        RotorpyPlant(PARAMS, TS, wind=Wind(mean=(3.0, 0.0, 0.0)))


def test_a_wind_of_the_wrong_shape_is_named(rotorpy):
    plant = RotorpyPlant(PARAMS, TS, effects(rotor_drag=1e-4), wind=lambda t: (1.0, 2.0))
    with pytest.raises(ValueError, match=r"wind\(t\) must be a finite array of shape \(3,\)"):
        plant.step(np.zeros(12), np.full(4, HOVER))


@pytest.mark.parametrize("make, match", [
    (lambda: effects(motor_lag=-0.01), "motor_lag must be a finite number >= 0"),
    (lambda: effects(rotor_drag=np.nan), "rotor_drag must be a finite number >= 0"),
    (lambda: effects(blade_flapping=np.inf), "blade_flapping must be a finite number"),
    (lambda: effects(thrust_scale=0.0), "thrust_scale must be a finite number > 0"),
    (lambda: effects(mass_scale=np.nan), "mass_scale must be a finite number > 0"),
    (lambda: effects(parasitic_drag=(0.01, -0.01, 0.01)),
     "parasitic_drag must be 3 finite numbers >= 0"),
    (lambda: effects(com_offset=(0.01, np.nan, 0.0)), "com_offset must be 3 finite"),
    (lambda: RotorpyPlant(ts=0.0), r"ts \(s\) must be a finite number > 0"),
    (lambda: RotorpyPlant(rtol=-1.0), "rtol must be a finite number > 0"),
    (lambda: RotorpyPlant(effects={"motor_lag": 0.03}), "effects must be a PlantParams"),
    (lambda: RotorpyPlant(wind=(3.0, 0.0, 0.0)), "wind must be a callable"),
])
def test_bad_input_is_named_at_construction(make, match):
    """These checks come before rotorpy is imported: they hold without it too."""
    with pytest.raises(ValueError, match=match):
        make()


def test_without_rotorpy_the_plant_names_the_extra(monkeypatch):
    for name in ("rotorpy", "rotorpy.vehicles", "rotorpy.vehicles.multirotor"):
        monkeypatch.setitem(sys.modules, name, None)  # import rotorpy now raises ImportError
    with pytest.raises(ImportError, match=r'rotorpy 3\.0\.0.*pip install -e "\.\[hardware\]"'):
        RotorpyPlant(PARAMS, TS)


def test_without_rotorpy_the_package_imports():
    code = ("import sys; sys.modules['rotorpy'] = None; import paper_repro, paper_repro.sim, "
            "paper_repro.sim.rotorpy_plant, paper_repro.world.wind; "
            "print(paper_repro.config.PlantParams(simulator='rotorpy', motor_lag=0.03)"
            ".motor_lag)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "0.03"
