"""Writing the demo's files into a folder: the project's program files (``project.program_files``:
program.mod, program_fc.mod, targets.csv, samples.csv, settings.json), workpiece.stl and
summary.json,
and project.npz (``project.save_project_file``)."""

from __future__ import annotations

import json
from pathlib import Path

from ..pipeline import DemoResult


def write_demo_outputs(result: DemoResult, out_dir: str | Path) -> list[Path]:
    """Write every output file into ``out_dir`` (created if needed); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = dict(result.files)
    if result.module_text_fc is None:
        files.pop("program_fc.mod", None)
    files["summary.json"] = json.dumps(result.summary(), indent=2) + "\n"
    written = []
    for name, text in files.items():
        path = out / name
        path.write_text(text)
        written.append(path)
    if result.project is not None:  # what `robomach machine --from` and the workbench open
        from ..project import PROJECT_FILE, save_project_file

        written.append(save_project_file(result.project, out / PROJECT_FILE))
    stl = out / "workpiece.stl"
    result.workpiece.mesh_in_base().export(stl)
    written.append(stl)
    return written
