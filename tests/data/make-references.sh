#!/usr/bin/env bash
# Renders the reference images that tests/integration/photon.rs and tests/integration/denoise.rs
# compare against: long path-traced renders of small images. They are
# committed; rerun this only when the scenes change, never to make a test
# pass.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
(cd "$root" && cargo build --release --quiet)
trazo="$root/target/release/trazo"
# The Cornell box, 32×32.
"$trazo" render -q --width 32 --height 32 --spp 32768 --seed 101 -o "$here/cornell-32-ref.exr"
# The Cornell box, 64×64 (for the denoisers).
"$trazo" render -q --width 64 --height 64 --spp 8192 --seed 103 -o "$here/cornell-64-ref.exr"
# The caustic scene, 64×48, path traced with next-event estimation and MIS.
"$trazo" render -q "$root/scenes/caustic.toml" --integrator path --width 64 --height 48 --spp 131072 --seed 102 -o "$here/caustic-64-ref.exr"
# Veach's door, 40×30, by bidirectional path tracing (the path tracer would
# take days): the equal-time tests of tests/integration/equal_time.rs.
"$trazo" render -q "$root/scenes/door.toml" --integrator bdpt --width 40 --height 30 --spp 16384 --seed 104 -o "$here/door-40-ref.exr"
# The door at its own size, 320×240, by BDPT (Metropolis light transport
# against BDPT in tests/integration/equal_time.rs; 4.5 min on two cores).
"$trazo" render -q "$root/scenes/door.toml" --integrator bdpt --spp 1024 --seed 99 -o "$here/door-320-ref.exr"
# The caustic box, 32×32, path traced (none of the integrators compared there).
"$trazo" render -q "$root/scenes/caustic-box.toml" --integrator path --width 32 --height 32 --spp 131072 --seed 105 -o "$here/caustic-box-32-ref.exr"
# The caustic in a glossy mirror, 32×24, by bidirectional path tracing.
"$trazo" render -q "$root/scenes/caustic-mirror.toml" --integrator bdpt --width 32 --height 24 --spp 32768 --seed 106 -o "$here/caustic-mirror-32-ref.exr"
