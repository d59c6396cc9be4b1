"""One hostile scenario against an extracted python-backend FMU, in a process of its own.

usage: python fmu_hostile_child.py EXTRACTED_FMU SCENARIO

Run by tests/fmu/test_fmu_python_hostile.py: a crash of the host kills this process, not pytest.
Prints one JSON object (the scenario's findings) as its last line and exits 0 when the host
survived every call, including the garbage collections and frees at the end.
"""

from __future__ import annotations

import gc
import json
import math
import sys
from pathlib import Path
from typing import Any

from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from fmu_support import Driver, open_fmu

OK = 0


def status(call: Any, *args: Any) -> int:
    """The FMI status of ``call(*args)`` (fmpy raises on anything worse than a warning)."""
    try:
        call(*args)
    except FMICallException as exc:
        return exc.status
    return OK


def slave_refcounts() -> list[int]:
    """References to the slave class, its instances and their log queues (this process hosts
    the FMU's interpreter too, so they are visible here)."""
    modules = [m for name, m in sys.modules.items() if name.startswith("gatetwin_slave_")]
    cls = modules[0].GatetwinPlant
    instances = [o for o in gc.get_objects() if type(o) is cls]
    return (
        [sys.getrefcount(cls)]
        + [sys.getrefcount(o) for o in instances]
        + [sys.getrefcount(o.log_queue) for o in instances]
    )


def serialized(d: Driver) -> bytes:
    state = d.slave.getFMUstate()
    data = bytes(d.slave.serializeFMUstate(state))
    d.slave.freeFMUstate(state)
    return data


def refused_calls(d: Driver) -> dict[str, Any]:
    d.start(20.0, 50.0)
    output_vr = d.vr[d.output]
    before = slave_refcounts()
    statuses = []
    for _ in range(40):
        statuses.append(status(d.slave.setReal, [output_vr], [1.0]))
        statuses.append(status(d.slave.setReal, [10**6], [1.0]))
        statuses.append(status(d.slave.getInteger, [0]))
        statuses.append(status(d.slave.getReal, [10**6]))
    after = slave_refcounts()
    step = status(d.slave.doStep, 0.0, d.step_s)
    level = d.level()
    reset = status(d.slave.reset)
    d.start(20.0, 50.0)
    return {"statuses": statuses, "refcounts_before": before, "refcounts_after": after,
            "step_after": step, "level_after": level, "reset": reset,
            "step_after_reset": status(d.slave.doStep, 0.0, d.step_s)}  # fmt: skip


def _bad_states(good: bytes) -> dict[str, bytes]:
    """Serialised states this FMU must refuse, derived from a good one."""
    payload = json.loads(good)

    def variant(change: Any) -> bytes:
        copy = json.loads(good)
        change(copy)
        return json.dumps(copy).encode()

    # a list of the family's dynamic state (the physical family has none: then real)
    lists = [v for v in payload["state"]["dyn"].values() if isinstance(v, list)]
    lists.append(payload["state"]["real"])
    longer = next(i for i, v in enumerate(payload["state"]["dyn"].values())
                  if isinstance(v, list)) if len(lists) > 1 else None  # fmt: skip
    return {
        "garbage bytes": b"\xff\x00garbage",
        "not an object": b"[1, 2]",
        "empty object": b"{}",
        "other model": variant(lambda p: p.update(guid="{00000000-0000-0000-0000-0}")),
        "other version": variant(lambda p: p.update(version=2)),
        "missing key": variant(lambda p: p["state"].pop("fx")),
        "extra key": variant(lambda p: p["state"].update(extra=1.0)),
        "short real": variant(lambda p: p["state"]["real"].pop()),
        "NaN value": variant(lambda p: p["state"]["real"].__setitem__(0, math.nan)),
        "infinite time": variant(lambda p: p["state"].update(time_s=math.inf)),
        "text for a number": variant(lambda p: p["state"]["dyn"].update(x="1.0")),
        "flag not boolean": variant(lambda p: p["state"].update(initialized=1)),
        "list size": variant(
            lambda p: (
                list(p["state"]["dyn"].values())[longer]
                if longer is not None
                else p["state"]["real"]
            ).extend([0.0] * 5000)
        ),
        "nested garbage": variant(lambda p: p["state"]["fx"].update(gate_mm=[1.0])),
        "truncated": good[: len(good) // 2],
    }


def state_restores(d: Driver) -> dict[str, Any]:
    d.start(20.0, 50.0)
    d.slave.doStep(0.0, d.step_s)
    good = serialized(d)
    d.set_inputs(30.0, 60.0)
    d.slave.doStep(d.step_s, d.step_s)
    current = serialized(d)
    results = {}
    for name, data in _bad_states(good).items():
        handle = d.slave.deSerializeFMUstate(data)
        results[name] = [status(d.slave.setFMUstate, handle), serialized(d) == current]
        d.slave.freeFMUstate(handle)
    handle = d.slave.deSerializeFMUstate(good)
    restored = status(d.slave.setFMUstate, handle)
    d.slave.freeFMUstate(handle)
    return {"results": results, "good_restore": restored, "good_back": serialized(d) == good,
            "step_after": status(d.slave.doStep, d.step_s, d.step_s)}  # fmt: skip


def double_free(d: Driver) -> dict[str, Any]:
    d.start(20.0, 50.0)
    for _ in range(30):
        state = d.slave.getFMUstate()
        for _ in range(3):
            d.slave.freeFMUstate(state)
            litter = [{"k": [float(i)]} for i in range(200)]  # reuses memory a free released
        gc.collect()
        del litter
    kept = d.slave.getFMUstate()
    d.slave.doStep(0.0, d.step_s)
    restore = status(d.slave.setFMUstate, kept)
    d.slave.freeFMUstate(kept)
    gc.collect()
    cls = next(m for n, m in sys.modules.items() if n.startswith("gatetwin_slave_")).GatetwinPlant
    handles = getattr(cls, "_handles", [])
    return {"restore": restore, "step_after": status(d.slave.doStep, 0.0, d.step_s),
            "handle_refcounts": [sys.getrefcount(h) for h in handles]}  # fmt: skip


def after_terminate(d: Driver) -> dict[str, Any]:
    d.start(20.0, 50.0)
    d.slave.terminate()
    return {"step": status(d.slave.doStep, 0.0, d.step_s),
            "set": status(d.slave.setReal, [d.vr["opening_mm"]], [25.0]),
            "get": status(d.level)}  # fmt: skip


def long_steps(d: Driver, steps: list[float]) -> dict[str, Any]:
    d.start(20.0, 50.0)
    results = []
    for h in steps:
        results.append(status(d.slave.doStep, d.time_s, h))
        if results[-1] == OK:
            d.time_s += h
    return {"results": results}


def refused_initialisation(d: Driver, name: str, value: float) -> dict[str, Any]:
    d.slave.setupExperiment(startTime=0.0)
    d.slave.enterInitializationMode()
    d.set_inputs(30.0, 50.0)  # 10 mm away from the reference opening
    original = d.slave.getReal([d.vr[name]])[0]
    d.slave.setReal([d.vr[name]], [value])
    first = status(d.slave.exitInitializationMode)
    gc.collect()
    d.slave.setReal([d.vr[name]], [original])  # the refusal left the instance as it was
    second = status(d.slave.exitInitializationMode)
    return {"exit": first, "retry": second, "step": status(d.slave.doStep, 0.0, d.step_s)}


def envelope(d: Driver, inputs: list[list[float]]) -> dict[str, Any]:
    d.start(*inputs[0])
    for opening, flow in inputs[1:]:
        d.step(d.step_s, opening, flow)
    return {}


def wrong_guid(extracted: str) -> dict[str, Any]:
    md = read_model_description(extracted)
    slave = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}",
                      unzipDirectory=extracted, instanceName="g",
                      modelIdentifier=md.coSimulation.modelIdentifier)  # fmt: skip
    slave.instantiate()
    accepted = bool(slave.component)
    slave.freeInstance()
    del slave
    gc.collect()  # as after every other scenario: the slave's references go before the exit
    return {"accepted": accepted}


def run(d: Driver, scenario: str, args: list[str]) -> dict[str, Any]:
    if scenario == "state_restores":
        return state_restores(d)
    if scenario == "long_steps":
        return long_steps(d, json.loads(args[1]))
    if scenario == "refused_initialisation":
        return refused_initialisation(d, args[1], float(args[2]))
    if scenario == "envelope":
        return envelope(d, json.loads(args[1]))
    simple = {"refused_calls": refused_calls, "double_free": double_free,
              "after_terminate": after_terminate}  # fmt: skip
    return simple[scenario](d)


def main() -> int:
    extracted, scenario, *args = sys.argv[1:]
    if scenario == "wrong_guid":
        print(json.dumps(wrong_guid(extracted)))
        return 0
    d = open_fmu(Path(extracted))
    d.step_s = float(args[0]) if args else 1.2
    found = run(d, scenario, args)
    found["messages"] = d.messages
    d.close()
    gc.collect()  # a slave left with unbalanced references crashes here
    print(json.dumps(found))
    return 0


if __name__ == "__main__":
    sys.exit(main())
