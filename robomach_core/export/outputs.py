"""Writing the demo's files into a folder: the project's program files (``project.program_files``:
the program in each language of the arm, e.g. program.mod and program_fc.mod, targets.csv,
samples.csv, settings.json), workpiece.stl and summary.json, and project.npz
(``project.save_project_file``)."""

from __future__ import annotations

import json
from pathlib import Path

from ..pipeline import DemoResult


def write_demo_outputs(result: DemoResult, out_dir: str | Path) -> list[Path]:
    """Write every output file into ``out_dir`` (created if needed); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = dict(result.files)
    if result.module_text_fc is None:  # no force-controlled variant asked for
        files = {k: v for k, v in files.items() if not k.startswith("program_fc.")}
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
