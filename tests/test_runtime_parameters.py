"""The weights and the barrier parameters are numbers the compiled linearisation reads at run
time: another value builds nothing, and the code computes with the value it is given."""

import dataclasses

import numpy as np

from paper_repro import Config, NMPCParams
from paper_repro._native import function_source
from paper_repro.config import BarrierParams, DistanceParams, SimulationParams
from paper_repro.solvers.rti import RealTimeNMPC

BASE = Config(nmpc=NMPCParams(horizon=10, region_slots=1, points_per_region=8),
              simulation=SimulationParams(scenario="encounter"))
OTHER = dataclasses.replace(
    BASE, nmpc=dataclasses.replace(BASE.nmpc, q=tuple(2.5 * np.asarray(BASE.nmpc.q)),
                                   r=(1.0, 2.0, 3.0, 4.0), t=(500.0, 700.0, 900.0)),
    barrier=BarrierParams(mu=3.0, kappa=7.0, delta=0.9, d_min=1.5),
    distance=DistanceParams(eta=0.5, sigma=1.6))


def _sources(config, **options):
    """The C of every function the controller compiles: what a build is keyed by."""
    ctl = RealTimeNMPC(config, compile=False, capacities=(), **options)
    return {function_source(fn) for rung in ctl.ladder.rungs for fn in rung[1:]}


def test_other_weights_and_barrier_parameters_build_nothing_new():
    for shared in (False, True):
        built = _sources(BASE, shared_barrier=shared)
        assert len(built) == 2  # the linearisation and the values
        assert _sources(OTHER, shared_barrier=shared) == built
        # a change of structure builds again: another horizon
        longer = dataclasses.replace(BASE, nmpc=dataclasses.replace(BASE.nmpc, horizon=11))
        assert _sources(longer, shared_barrier=shared).isdisjoint(built)


def test_the_code_computes_with_the_weights_it_is_given():
    """Nothing in view: the cost at an iterate is Σ‖x_j − x_a‖²_Q + ‖u_j − u_a‖²_R +
    ‖y_a − y_t‖²_T with the configuration's weights (the empty slot's penalty is 0)."""
    rng = np.random.default_rng(4)
    for cfg in (BASE, OTHER):
        ctl = RealTimeNMPC(cfg, compile=False, capacities=())
        ocp, n = ctl.ocp, cfg.nmpc.horizon
        x0 = rng.normal(size=ocp.nx)
        X, U = rng.normal(size=(n, ocp.nx)), rng.normal(size=(n, ocp.nu))
        a = rng.normal(size=ocp.na)
        target = rng.normal(size=3)
        rung = ctl.ladder.for_scan(())
        params = np.concatenate([target, ctl.ladder.pack((), ocp.output(x0), rung.scan),
                                 ocp.runtime_values])
        cost = ctl.ladder.evaluate(rung.values, x0, X, U, a, params)[0][0]
        x_a, u_a = (np.asarray(v, float).ravel() for v in ocp.equilibrium(a))
        q, r, t = (np.asarray(w, float) for w in (cfg.nmpc.q, cfg.nmpc.r, cfg.nmpc.t))
        xs = np.vstack([x0, X[:-1]])  # x_0..x_{N−1}, each with u_j
        expected = (np.sum(q * (xs - x_a) ** 2) + np.sum(r * (U - u_a) ** 2)
                    + np.sum(t * (ocp.output(x_a) - target) ** 2))
        assert cost == np.float64(expected) or abs(cost - expected) <= 1e-9 * expected
