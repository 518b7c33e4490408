"""Writing the demo's files: program.mod, samples.csv, targets.csv, workpiece.stl, summary.json,
settings.json."""

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
        "settings.json": json.dumps(settings_document(result), indent=2) + "\n",
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


def settings_document(result: DemoResult) -> dict:
    """Every setting that shaped the program (mm, N, s at the boundary), for settings.json."""
    st = result.settings
    post = st.postprocess
    doc = {
        "robot": st.robot,
        "workpiece": result.workpiece.name,
        "T_base_wobj_mm": [
            [round(float(v) * (1e3 if j == 3 and i < 3 else 1.0), 6) for j, v in enumerate(row)]
            for i, row in enumerate(result.workpiece.T_base_wobj)
        ],
        "tool": {
            "name": st.tool.name,
            "tcp_offset_mm": [v * 1e3 for v in st.tool.tcp_offset_m],
            "mass_kg": st.tool.mass_kg,
            "com_mm": [v * 1e3 for v in st.tool.com_m],
            "shape": st.tool.shape,
            "radius_mm": st.tool.radius_m * 1e3,
        },
        "path_learning": {
            "force_N": st.force_N,
            "speed_mm_s": st.speed_m_s * 1e3,
            "wall_side": st.wall_side,
            "seed": st.seed,
        },
        "postprocess": {
            "force_min_N": post.force_min_N,
            "force_max_N": post.force_max_N,
            "tolerance_mm": st.tolerance_m * 1e3,
            "speed_mean_mm_s": post.speed_mean_m_s * 1e3,
            "speed_min_mm_s": post.speed_min_m_s * 1e3,
            "contact_stiffness_N_mm": post.contact_stiffness_N_m * 1e-3,
        },
        "cmrr": None,
        "compensation": None,
    }
    if st.cmrr is not None:
        from ..cmrr import settings_to_dict

        doc["cmrr"] = settings_to_dict(st.cmrr)
    if st.compensation is not None:
        from ..stiffness.settings import settings_to_dict as compensation_to_dict

        doc["compensation"] = compensation_to_dict(st.compensation)
    return doc
