"""Writing the demo's files: program.mod, samples.csv, targets.csv, workpiece.stl, summary.json."""

from __future__ import annotations

import json
from pathlib import Path

from ..pipeline import DemoResult
from .tables import samples_csv, targets_csv


def write_demo_outputs(result: DemoResult, out_dir: str | Path) -> list[Path]:
    """Write every output file into ``out_dir`` (created if needed); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {
        "program.mod": result.module_text,
        "samples.csv": samples_csv(result.recording, result.processed.keep_mask),
        "targets.csv": targets_csv(result.processed.targets),
        "summary.json": json.dumps(result.summary(), indent=2) + "\n",
    }
    if result.module_text_fc is not None:
        files["program_fc.mod"] = result.module_text_fc
    written = []
    for name, text in files.items():
        path = out / name
        path.write_text(text)
        written.append(path)
    stl = out / "workpiece.stl"
    result.workpiece.mesh_in_base().export(stl)
    written.append(stl)
    return written
