#!/usr/bin/env bash
# Re-imports the seven Mitsuba scenes of scenes/mitsuba/ into scenes/imported/NAME.toml with
# `plexus import`, and records each import's warnings in scenes/imported/NAME.warnings. The TOML
# files refer to the meshes and textures where they are, in scenes/mitsuba/, by paths relative to
# scenes/imported/; `tests/images/import.rs` checks that the committed files are exactly what the importer
# writes today. The XML paths written into the TOML comments and the warnings are relative to the
# repository root, where this script runs.
#
# Usage: scripts/import-scenes.sh        (from anywhere; the binary is $PLEXUS or the release build)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/plexus-binary.sh
if [[ -z "${PLEXUS:-}" ]]; then
    cargo build --release --quiet
fi
plexus_binary import-scenes.sh
data=scenes/mitsuba
mkdir -p scenes/imported
status=0
# name           XML file                 extra import options
while read -r name xml extra; do
    echo "== $name" >&2
    # shellcheck disable=SC2086
    "$plexus" import "$data/$name/$xml" --out "scenes/imported/$name.toml" $extra \
        2> >(tee "scenes/imported/$name.warnings" >&2) || status=1
done <<'LIST'
cornell-box    cbox.xml
veach-ajar     scene_v3.xml --skip-missing-meshes
veach-lamp     scene.xml
torus          scene.xml
staircase      scene.xml
breakfast-room scene.xml
living-room    scene.xml
LIST
exit $status
