"""Reads a Rerun recording of `icrflow run` or `icrflow plan` back with the Python Rerun SDK of the same version
as the Rust crate (rerun-sdk, pinned in bench/requirements.txt), no code of ours. Used by
tests/visualizer.rs.

    python tests/read_rrd.py RECORDING.rrd [MORE.rrd ...]
    python tests/read_rrd.py --png SCREENSHOT.png

Prints one JSON object:
  recording_ids   the recording ids in the files
  entities        every entity path
  rows            rows per entity path (every row logged, static ones included)
  steps           the plan-step numbers logged on /plan/step (the `step` timeline), in order
  phases          [step, phase] of every /timeseries/phase row
  rendezvous      [step, points] of every /scene/object/rendezvous row with points
  quality_min     the smallest value logged on /timeseries/quality/alpha_star
  alpha           the values logged on /timeseries/quality/alpha (distinct)
  dropped_max     the last count of dropped frames (/timeseries/dropped_frames)
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


def png(path: str) -> int:
    """Prints the size of a PNG and how many distinct colours it has (a blank one has one)."""
    from PIL import Image

    with Image.open(path) as image:
        rgb = image.convert("RGB")
        pixels = rgb.get_flattened_data() if hasattr(rgb, "get_flattened_data") else rgb.getdata()
        colours = len(set(pixels))
        print(json.dumps({"width": rgb.width, "height": rgb.height, "colours": colours}))
    return 0


def main() -> int:
    if sys.argv[1] == "--png":
        return png(sys.argv[2])
    ids, entities = set(), set()
    rows = collections.Counter()
    steps, quality, alpha, dropped, phases, rendezvous = [], [], set(), [], [], []
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
                "alpha": sorted(alpha),
                "dropped_max": max(dropped) if dropped else None,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
