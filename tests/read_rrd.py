"""Reads a Rerun recording of `icrflow run` or `icrflow plan` back with the Python Rerun SDK of the same version
as the Rust crate (rerun-sdk, pinned in bench/requirements.txt), no code of ours. Used by
tests/visualizer.rs and tests/run_mujoco.rs.

    python tests/read_rrd.py RECORDING.rrd [MORE.rrd ...]
    python tests/read_rrd.py --png SCREENSHOT.png [OTHER.png]
    python tests/read_rrd.py --blueprint RECORDING.rrd

Prints one JSON object:
  recording_ids   the recording ids in the files
  entities        every entity path
  rows            rows per entity path (every row logged, static ones included)
  steps           the plan-step numbers logged on /plan/step (the `step` timeline), in order
  phases          [step, phase] of every /timeseries/phase row
  rendezvous      [step, points] of every /scene/object/rendezvous row with points
  quality_min     the smallest value logged on /timeseries/quality/alpha_star
  alpha           the values logged on /timeseries/quality/alpha (distinct)
  true_rotation_max  the largest value logged on /timeseries/angles/object_true (a
                  simulated plant's true rotation)
  true_tilt_max   the largest value logged on /timeseries/angles/object_tilt (its true
                  rotation off the plan's axis)
  dropped_max     the last count of dropped frames (/timeseries/dropped_frames)

With --png: the picture's width, height and number of distinct colours (a blank one has
one); with a second picture of the same size, also `changed`, the fraction of pixels that
differ between the two by more than 24 (of 255) in some channel.

With --blueprint: the layout the recording opens with, read from its blueprint store:
  views           [{"name", "class", "origin"}] of every view
  eyes            {view name: {"position", "look_target", "eye_up"}} of the 3D views' cameras
  panels          {"blueprint_panel" | "selection_panel" | "time_panel": state}
"""

import collections
import json
import sys

import pyarrow as pa
import pyarrow.compute as pc
from rerun.experimental import RrdReader

SCALARS = "Scalars:scalars"
POSITIONS = "Points3D:positions"


def values(store, entity: str) -> list:
    """Every scalar logged on `entity`, in the order of the `step` then `time` timelines."""
    batches = [
        ch.to_record_batch()
        for ch in store.stream().filter(content=entity, components=SCALARS)
    ]
    if not batches:
        return []
    table = pa.concat_tables([pa.Table.from_batches([b]).select(["step", SCALARS]) for b in batches])
    table = table.sort_by("step")
    return pc.list_flatten(table[SCALARS]).to_pylist()


def rows_by_step(store, entity: str, component: str) -> list:
    """[step, value] for each row of `entity` holding `component`: the scalar, or the number of
    instances for a point cloud."""
    out = []
    for ch in store.stream().filter(content=entity, components=component):
        batch = ch.to_record_batch()
        for step, value in zip(batch.column("step").to_pylist(), batch.column(component).to_pylist()):
            if value is None:
                continue
            out.append([step, value[0] if component == SCALARS else len(value)])
    return sorted(out)


def png(path: str, other: str | None = None) -> int:
    """Prints the size of a PNG, how many distinct colours it has, and how much of it differs
    from `other`."""
    from PIL import Image, ImageChops

    with Image.open(path) as image:
        rgb = image.convert("RGB")
        pixels = rgb.get_flattened_data() if hasattr(rgb, "get_flattened_data") else rgb.getdata()
        out = {"width": rgb.width, "height": rgb.height, "colours": len(set(pixels))}
        if other is not None:
            with Image.open(other) as second:
                b = second.convert("RGB")
                if b.size != rgb.size:
                    out["changed"] = None
                else:
                    diff = ImageChops.difference(rgb, b).convert("L").point(lambda v: 255 if v > 24 else 0)
                    out["changed"] = diff.histogram()[255] / (rgb.width * rgb.height)
        print(json.dumps(out))
    return 0


def blueprint(path: str) -> int:
    """Prints the views, 3D eyes and panel states of the recording's blueprint."""
    reader = RrdReader(path)
    rows = collections.defaultdict(dict)
    for entry in reader.blueprints():
        for ch in reader.stream(store=entry):
            batch = ch.to_record_batch()
            for name in batch.schema.names:
                if ":" not in name:
                    continue
                for value in batch.column(name).to_pylist():
                    if value is not None:
                        rows[ch.entity_path][name.split(":")[-1]] = value
    def one(v):
        return v[0] if isinstance(v, list) and len(v) == 1 else v
    views, eyes, panels = [], {}, {}
    for entity, fields in rows.items():
        path = entity.strip("/")
        if path.startswith("view/") and path.count("/") == 1 and "class_identifier" in fields:
            name = one(fields.get("display_name"))
            views.append({"name": name, "class": one(fields["class_identifier"]), "origin": one(fields.get("space_origin"))})
            eye = rows.get(entity + "/EyeControls3D") or rows.get("/" + path + "/EyeControls3D")
            if eye:
                eyes[name] = {k: one(eye.get(k)) for k in ("position", "look_target", "eye_up")}
        elif path in ("blueprint_panel", "selection_panel", "time_panel") and "state" in fields:
            state = one(fields["state"])
            panels[path] = {1: "hidden", 2: "collapsed", 3: "expanded"}.get(state, state)
    print(json.dumps({"views": sorted(views, key=lambda v: v["name"] or ""), "eyes": eyes, "panels": panels}))
    return 0


def main() -> int:
    if sys.argv[1] == "--png":
        return png(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None)
    if sys.argv[1] == "--blueprint":
        return blueprint(sys.argv[2])
    ids, entities = set(), set()
    rows = collections.Counter()
    steps, quality, alpha, dropped, phases, rendezvous = [], [], set(), [], [], []
    true_rotation, true_tilt = [], []
    for path in sys.argv[1:]:
        reader = RrdReader(path)
        ids.update(r.recording_id for r in reader.recordings())
        store = reader.stream().collect()
        entities.update(store.schema().entity_paths())
        for ch in store.stream():
            rows[ch.entity_path] += ch.num_rows
        steps += values(store, "/plan/step")
        quality += values(store, "/timeseries/quality/alpha_star")
        alpha.update(values(store, "/timeseries/quality/alpha"))
        dropped += values(store, "/timeseries/dropped_frames")
        true_rotation += values(store, "/timeseries/angles/object_true")
        true_tilt += values(store, "/timeseries/angles/object_tilt")
        phases += rows_by_step(store, "/timeseries/phase", SCALARS)
        rendezvous += rows_by_step(store, "/scene/object/rendezvous", POSITIONS)
    print(
        json.dumps(
            {
                "recording_ids": sorted(ids),
                "entities": sorted(entities),
                "rows": dict(rows),
                "steps": steps,
                "phases": sorted(phases),
                "rendezvous": sorted(rendezvous),
                "quality_min": min(quality) if quality else None,
                "true_rotation_max": max(true_rotation) if true_rotation else None,
                "true_tilt_max": max(true_tilt) if true_tilt else None,
                "alpha": sorted(alpha),
                "dropped_max": max(dropped) if dropped else None,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
