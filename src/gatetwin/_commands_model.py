"""Argument parsing and printing of ``identify``, ``models`` and ``export`` (no logic)."""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path
from typing import Any

from gatetwin._io import write_json_atomic, write_text_atomic
from gatetwin.errors import GatetwinError, IdentificationError

TEST_CHOICES = ("step", "prbs")


def add_identify_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("path", metavar="RECORD.csv")
    parser.add_argument("--test", choices=TEST_CHOICES, help="override the sidecar/detection")
    parser.add_argument("--gauge", help="gauge (default: every gauge for step, 3F for prbs)")
    parser.add_argument(
        "--orders", nargs="+", metavar="N",
        help="ARX orders NA NB NK (default the paper's 2 2 1) or 'auto' (order search)",
    )  # fmt: skip
    parser.add_argument(
        "--criterion", default="bic", choices=("bic", "aic", "holdout_rmse", "holdout_fit"),
        help="criterion of --orders auto (default bic)",
    )  # fmt: skip
    parser.add_argument("--json", metavar="OUT.json", required=True)


def _orders(values: list[str] | None) -> tuple[int, int, int] | str:
    if values is None:
        return (2, 2, 1)
    if values == ["auto"]:
        return "auto"
    try:
        na, nb, nk = (int(v) for v in values)
    except ValueError:
        raise GatetwinError(
            f"--orders: expected three integers NA NB NK or 'auto', got {' '.join(values)}"
        ) from None
    return (na, nb, nk)


def run_identify(args: argparse.Namespace) -> int:
    from gatetwin.identify import identify_prbs, identify_step
    from gatetwin.records import read_record

    record = read_record(args.path, test=args.test)
    if record.test == "step" and args.orders is not None:
        raise GatetwinError(f"{args.path}: --orders applies to PRBS records, this is a step test")
    if record.test == "step":
        result = identify_step(record, args.gauge).to_dict()
        for g, res in result["gauges"].items():
            p, f = res["paper"], res["fit"]
            print(f"{g}: paper K {p['K']:.2f} L {p['L_s']:.1f} s T {p['T_s']:.1f} s | "
                  f"fit K {f['K']:.2f}±{f['K_se']:.2f} L {f['L_s']:.2f}±{f['L_se']:.2f} s "
                  f"T {f['T_s']:.1f}±{f['T_se']:.1f} s")  # fmt: skip
    elif record.test == "prbs":
        res = identify_prbs(record, gauge=args.gauge or "3F", orders=_orders(args.orders),
                            criterion=args.criterion)  # fmt: skip
        result = res.to_dict()
        print(f"ARX({result['na']},{result['nb']},{result['nk']}) at {result['gauge']}: "
              f"a {result['a']} b {result['b']}; one-step R² {result['one_step']['r2']:.3f}, "
              f"free-run fit {result['simulation']['fit_percent']:.1f} %")  # fmt: skip
    else:
        raise IdentificationError(
            f"{args.path}: a {record.test!r} record has no method; use --test step or prbs"
        )
    write_json_atomic(args.json, result)
    return 0


def add_models_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--records", metavar="DIR", help="records folder (default: the bundled records)"
    )
    parser.add_argument("--out", metavar="DIR", required=True, help="where to write the models")


def schema_text() -> str:
    return (resources.files("gatetwin") / "data" / "model_schema.json").read_text("utf-8")


def write_models(models: dict[str, dict[str, Any]], out: Path) -> list[Path]:
    """Write every model file and the schema into ``out`` (each file atomically)."""
    paths = [write_text_atomic(out / "schema.json", schema_text())]
    for name, doc in sorted(models.items()):
        paths.append(write_json_atomic(out / f"{name}.json", doc))
    return paths


def run_models(args: argparse.Namespace) -> int:
    from gatetwin.bundled import bundled_records_dir
    from gatetwin.identify.suite import identify_folder

    folder = Path(args.records) if args.records else bundled_records_dir()
    ident = identify_folder(folder)
    for path in write_models(ident.models, Path(args.out)):
        print(f"wrote {path}")
    return 0


def add_export_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("model", metavar="MODEL.json")
    parser.add_argument("--backend", choices=("c", "python"), required=True)
    parser.add_argument("--out", metavar="NAME.fmu", required=True)


def run_export(args: argparse.Namespace) -> int:
    from gatetwin.fmu import export_fmu
    from gatetwin.fmu.provenance import fmu_provenance
    from gatetwin.modelfile import read_model_file

    model = read_model_file(args.model)
    path = export_fmu(model.plant, args.out, backend=args.backend, model_name=model.name,
                      provenance=fmu_provenance(model))  # fmt: skip
    print(f"wrote {path}")
    return 0
