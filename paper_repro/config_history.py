"""How the settings of :mod:`paper_repro.config` changed since the committed evidence was
flown: the settings that moved between parts (:data:`MOVED`) and the ones added since
(:data:`ADDED`), so that an older ``config.json`` still loads and a run that flies as before
keeps its cache key."""

from __future__ import annotations

import json

MOVED = {
    ("nmpc", "solver"): ("solver", "nlp_solver"),
    ("nmpc", "sqp_iterations"): ("solver", "sqp_iterations"),
    ("nmpc", "line_search"): ("solver", "line_search"),
    ("nmpc", "qp_solver"): ("solver", "qp_solver"),
    ("simulation", "lidar_range"): ("sensor", "range"),
    ("simulation", "prediction"): ("nmpc", "prediction"),
    ("nmpc", "state_lower"): ("quadrotor", "state_lower"),
    ("nmpc", "state_upper"): ("quadrotor", "state_upper"),
    ("nmpc", "input_lower"): ("quadrotor", "input_lower"),
    ("nmpc", "input_upper"): ("quadrotor", "input_upper"),
}
"""Settings that moved between parts, (old part, old name) → (new part, new name): the
solver's options left the problem's ``nmpc`` part, the LiDAR's range and the prediction of
moving regions left the mission (``simulation``), and the quadrotor's boxes 𝒳 and 𝒰 joined
the rest of its data (``quadrotor``)."""

KEYED_IN_FORMER_PLACE = {("nmpc", "state_lower"): "t", ("nmpc", "state_upper"): "state_lower",
                         ("nmpc", "input_lower"): "state_upper",
                         ("nmpc", "input_upper"): "input_lower"}
"""Settings of :data:`MOVED` that a run's key, and a study's record of its runs, still name in
their former place (:func:`as_keyed`), each with the setting it followed there: they moved
after the committed evidence was flown, and a move changes no flight, so the keys and the
records stay as they were, byte for byte."""


ADDED = {
    ("barrier", "equilibrium_lookahead"): 0.0,
    ("sensor", "map_voxel"): 0.0,
    ("guide", None): None,
    ("guide", "set_point_filter"): 0.0,  # after ("guide", None): the part's defaults hold it
    ("simulation", "approach_time"): 150.0,
    ("tracker", None): None,
    ("solver", "relaxed_qp"): False,
    ("solver", "cold_start"): "rti",
    ("solver", "shared_barrier"): False,
    ("plant", None): None,
    ("simulation", "workspace_exit"): None,
    ("plant", "estimate_filter_time"): None,
}
"""Settings added after the committed evidence was flown, (part, name) → the value that flies
as before (the golden flights prove it). A run whose setting has that value is keyed as it was
before the setting existed (:meth:`Config.key_dict`), so the committed tables and a cache of
runs stay valid across the addition and nothing is flown again; any other value enters the key
like every setting. A setting enters here only with the commit that adds it. A whole part
added later is named ``(part, None)``: at its defaults it is left out of the key (its neutral
value, None, stands for the part's defaults)."""


def without_added(data: dict, defaults: dict) -> dict:
    """``data`` (a :meth:`Config.to_dict`, or one read from a ``config.json``) without the
    settings of :data:`ADDED` that hold their neutral value: what a run's key hashes.
    ``defaults`` is the default configuration (``Config().to_dict()``), whose parts are the
    neutral values of the parts added whole."""
    data = {part: dict(values) if isinstance(values, dict) else values
            for part, values in data.items()}
    for (part, name), neutral in ADDED.items():
        if name is None:
            # The settings added to the part later do not count: at its other defaults the
            # part flies as before, whatever they hold (the guide off ignores its filter).
            later = {n for p, n in ADDED if p == part and n is not None}
            if part in data and (_plain({k: v for k, v in data[part].items() if k not in later})
                                 == _plain({k: v for k, v in defaults[part].items()
                                            if k not in later})):
                del data[part]
        elif isinstance(data.get(part), dict) and data[part].get(name, None) == neutral:
            del data[part][name]
    return data


def as_keyed(data: dict) -> dict:
    """``data`` (a :meth:`Config.to_dict`) with the settings of :data:`KEYED_IN_FORMER_PLACE`
    moved back to their former place: the layout a run's key hashes and a study's
    ``study.json`` records."""
    data = {part: dict(values) if isinstance(values, dict) else values
            for part, values in data.items()}
    for (old_part, old_name), after in KEYED_IN_FORMER_PLACE.items():
        new_part, new_name = MOVED[(old_part, old_name)]
        if isinstance(data.get(new_part), dict) and new_name in data[new_part]:
            value, part = data[new_part].pop(new_name), data.setdefault(old_part, {})
            items = list(part.items())
            at = next((i + 1 for i, (k, _) in enumerate(items) if k == after), len(items))
            data[old_part] = dict(items[:at] + [(old_name, value)] + items[at:])
    return data


def keyed(data: dict, defaults: dict) -> dict:
    """What a run's key hashes of ``data`` (a :meth:`Config.to_dict`, or one read from a
    ``config.json``): :func:`without_added`, then :func:`as_keyed`."""
    return as_keyed(without_added(data, defaults))


def _plain(values: dict) -> dict:
    """``values`` as JSON holds them (a tuple is a list), so that a part read from a
    ``config.json`` compares equal to the same part of a :class:`Config`."""
    return json.loads(json.dumps(values, default=str))


def moved_settings(data: dict) -> dict:
    """``data`` (a :meth:`Config.to_dict`) with every setting of :data:`MOVED` in its new
    place; a setting given in both places is refused."""
    data = {part: dict(values) if isinstance(values, dict) else values
            for part, values in data.items()}
    for (old_part, old_name), (new_part, new_name) in MOVED.items():
        old = data.get(old_part)
        if not (isinstance(old, dict) and old_name in old):
            continue
        new = data.setdefault(new_part, {})
        if new_name in new:
            raise ValueError(f"config gives {old_part}.{old_name} (its former place) and "
                             f"{new_part}.{new_name}: give only {new_part}.{new_name}")
        new[new_name] = old.pop(old_name)
    return data


def with_added(data: dict) -> dict:
    """``data`` (read from a ``config.json`` or a key) with every setting of :data:`ADDED`
    that a part it gives lacks set to its neutral value: a part written before the setting
    existed (or keyed without it) flew as before it, whatever the setting's default is now.
    A part it does not give is left out, to take its defaults."""
    data = {part: dict(values) if isinstance(values, dict) else values
            for part, values in data.items()}
    for (part, name), neutral in ADDED.items():
        if name is not None and isinstance(data.get(part), dict):
            data[part].setdefault(name, neutral)
    return data
