#!/usr/bin/env bash
# Files what `device_run.sh series` brought back into the gallery:
#   bash scripts/series_harvest.sh series.tgz [GALLERY]       (GALLERY default docs/gallery)
#   bash scripts/series_harvest.sh series-concentrated.tgz [GALLERY]
# Each member run to its end gets its compact products in GALLERY/SCENE/MEMBER/ (config, time
# series, lowest modes, log, analysis/, and compare/: the comparison's CSVs, SVG figures (the
# velocity slice as PNG)) and its row in the scene's table: GALLERY/paper_dilute_series.csv
# (rows of the comparison's series.csv) for paper-dilute, GALLERY/paper_concentrated_series.csv
# (rows of its particle_statistics.csv, the table made with its header where there is none) for
# paper-concentrated; the archive's scene_name says which (paper-dilute where it has none). A
# member already in the table is left as it is; a member cut short (MEMBER-partial) is
# reported, not filed.
set -euo pipefail
archive="$1"
gallery="${2:-docs/gallery}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
tar xzf "$archive" -C "$tmp"
python3 - "$tmp" "$gallery" <<'PY'
import pathlib, shutil, sys

src, gallery = map(pathlib.Path, sys.argv[1:3])
named = src / "scene_name"
scene = named.read_text().strip() if named.exists() else "paper-dilute"
table_name, rows_name = {
    "paper-dilute": ("paper_dilute_series.csv", "series.csv"),
    "paper-concentrated": ("paper_concentrated_series.csv", "particle_statistics.csv"),
}.get(scene, (None, None))
if table_name is None:
    sys.exit(f"scene {scene}: no gallery table for it (paper-dilute, paper-concentrated)")
table = gallery / table_name
for partial in sorted(src.glob("*-partial")):
    print(f"{partial.name}: cut short, not filed")
compared = src / "compare" / rows_name
if not compared.exists():
    sys.exit(f"no compare/{rows_name} in the archive: no member finished")
new = compared.read_text().splitlines()
rows = table.read_text().splitlines() if table.exists() else [new[0]]
have = {r.split(",")[0] for r in rows[1:]}
if new[0] != rows[0]:
    sys.exit(f"{compared}: header differs from {table}:\n{new[0]}\n{rows[0]}")
keep = lambda p: (p.suffix in (".csv", ".md", ".toml", ".log", ".svg") and p.name != "velocity_slice.svg") or p.name == "velocity_slice.png"
for row in new[1:]:
    member = row.split(",")[0]
    if member in have:
        print(f"{member}: in {table} already, left as it is")
        continue
    if not (src / member).is_dir():
        print(f"{member}: no products in the archive, not filed")
        continue
    dest = gallery / scene / member
    for d, sub in ((src / member, ""), (src / "compare", "compare")):
        for f in sorted(d.rglob("*")):
            if f.is_file() and keep(f) and not f.name.endswith(".pvd"):
                to = dest / sub / f.relative_to(d)
                to.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(f, to)
    rows.append(row)
    have.add(member)
    print(f"{member}: filed into {dest} and {table}")
table.write_text("\n".join(rows) + "\n")
PY
