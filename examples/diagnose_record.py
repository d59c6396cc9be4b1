"""Diagnose a record: where a linear twin misses it, and which physical effect is missing."""

import gatetwin

# the gate 15 -> 20 -> 25 -> 30 mm and back at Q = 35 m3/h: far from one operating point
record = gatetwin.bundled_records_dir() / "Emoves35.csv"
found = gatetwin.diagnose(record, plots_dir=".")  # baseline: an FOPDT fitted to the record
print(f"{found.record}, gauge {found.gauge}: missing effect {found.named_effect!r}")
print(
    f"RMSE {found.rmse_before_mm:.2f} -> {found.rmse_after_mm:.2f} mm "
    f"(noise floor {found.noise_floor_mm:.2f} mm)"
)
for candidate in found.to_dict()["candidates"]:
    print(f"  {candidate['effect']:22s} score {candidate['score']}")
