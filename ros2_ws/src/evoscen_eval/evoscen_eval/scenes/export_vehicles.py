"""What an exported OpenSCENARIO vehicle declares of evoscen's vehicles (docs/export.md, "What is exported").

:func:`limits_of` reads the limits a recorded run's vehicles had from its scenario record: every vehicle
the ``vehicle`` section's speed cap, acceleration at full throttle and braking at full brake (the
single-track model's, :class:`~evoscen_sim.config.config_schema.VehicleParams`); a truck of the ``highd``
make-up's acceleration and braking capped by its driver, ``models.truck`` (``accel_mps2``,
``max_decel_mps2``). :func:`xosc_vehicle` writes them as the ``Performance``, the model's wheelbase
and steering limit as the ``Axles``, and names the vehicle by its class. :func:`policy_name` and
:func:`policy_code` turn the ``policy`` column into the words of ``evoscen:policy`` and back.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from evoscen_contract import contract as C
from evoscen_contract.contract import TRUCK_MIN_LENGTH_M


@dataclass(frozen=True)
class Limits:
    """A vehicle's limits as OpenSCENARIO's ``Performance`` and ``Axles`` declare them."""

    max_speed_mps: float
    max_accel_mps2: float
    max_decel_mps2: float
    wheelbase_m: float
    max_steer_rad: float


def _params(cls: type, raw: object):
    """``cls()`` with the recorded values of its fields in ``raw`` (a dict; others ignored)."""
    names = {f.name for f in dataclasses.fields(cls)}
    return dataclasses.replace(cls(), **{k: v for k, v in (raw if isinstance(raw, dict) else {}).items() if k in names})


def limits_of(scenario: dict | None) -> dict[str, Limits]:
    """``{"car": ..., "truck": ...}``: the limits of the run recorded with ``scenario`` (its resolved
    configuration; None: the defaults). ``truck`` applies to the trucks of the ``highd`` make-up (BVs longer
    than :data:`~evoscen_contract.contract.TRUCK_MIN_LENGTH_M`, driven by ``models.truck``)."""
    from evoscen_sim.config.config_schema import VehicleParams
    from evoscen_sim.model_registry import params_type_of

    scenario = scenario or {}
    v = _params(VehicleParams, scenario.get("vehicle"))
    car = Limits(float(v.max_speed_mps), float(v.max_accel_mps2), float(v.max_brake_mps2), float(v.wheelbase_m),
                 float(v.max_steer_rad))
    truck_type = params_type_of("truck")
    if truck_type is None:
        return {"car": car, "truck": car}
    t = _params(truck_type, (scenario.get("models") or {}).get("truck"))
    return {"car": car, "truck": dataclasses.replace(car, max_accel_mps2=min(car.max_accel_mps2, float(t.accel_mps2)),
                                                     max_decel_mps2=min(car.max_decel_mps2, float(t.max_decel_mps2)))}


def truck_driven(track, scenario: dict | None) -> bool:
    """``track`` (a :class:`~evoscen_eval.scenes.scenario_export.Track`) was driven by the truck driver: a BV
    of the ``highd`` make-up longer than the truck class's least length (a scenario without ``bvs.makeup``
    ran ``uniform``: no trucks)."""
    makeup = ((scenario or {}).get("bvs") or {}).get("makeup") or "uniform"
    return makeup == "highd" and track.role != C.ROLE_SUT and track.length_m > TRUCK_MIN_LENGTH_M


def policy_name(code: int) -> str:
    """The word of ``evoscen:policy`` for a ``policy`` column value (:data:`~evoscen_contract.contract.POLICY_NAMES`;
    an unknown code as its number)."""
    return C.POLICY_NAMES.get(int(code), str(int(code)))


def policy_code(text: str | None) -> int:
    """The ``policy`` code of an ``evoscen:policy`` value: a name of :data:`~evoscen_contract.contract.POLICY_CODES`
    or a number (files written before the names); -1 when absent or unknown."""
    if text is None:
        return -1
    if text in C.POLICY_CODES:
        return C.POLICY_CODES[text]
    try:
        return int(text)
    except ValueError:
        return -1


def xosc_vehicle(track, limits: Limits, height_m: float):
    """The ``Vehicle`` of ``track``: named by its class (``car``, ``truck``), its bounding box centred on the
    reference point, ``Performance`` and ``Axles`` from ``limits`` (the front axle half a wheelbase ahead of
    the box's centre, steering up to the model's limit; the rear half behind), and the ``evoscen:*``
    properties."""
    from scenariogeneration import xosc

    cat = xosc.VehicleCategory.truck if track.klass == "truck" else xosc.VehicleCategory.car
    bb = xosc.BoundingBox(track.width_m, track.length_m, height_m, 0.0, 0.0, 0.5 * height_m)
    half = 0.5 * limits.wheelbase_m
    track_width = 0.6 * track.width_m  # [choice] evoscen is 2-D (no track width, wheel size or height)
    veh = xosc.Vehicle(track.klass, cat, bb, xosc.Axle(limits.max_steer_rad, 0.8, track_width, half, 0.4),
                       xosc.Axle(0.0, 0.8, track_width, -half, 0.4), limits.max_speed_mps, limits.max_accel_mps2,
                       limits.max_decel_mps2)
    veh.add_property("evoscen:id", str(track.vid))
    veh.add_property("evoscen:role", "sut" if track.role == C.ROLE_SUT else "bv")
    veh.add_property("evoscen:policy", policy_name(track.policy))
    veh.add_property("evoscen:class", track.klass)
    return veh
