#!/usr/bin/env bash
# The README's sphere pictures (128^2, builtin:sky:9): the reference, the paper's estimator at
# 32 + 32 samples, and one light sample with fractional and integer counts, diffuse and Phong 150.
# Usage: ENVIS=target/release/envis bash docs/img/spheres.sh
set -euo pipefail
cd "$(dirname "$0")"
B="${ENVIS:-../../target/release/envis}"
t=$(mktemp -d)
for m in diffuse phong; do
  "$B" reference --env builtin:sky:9 --size 128 --brdf "$m" --out "$t/r.exr" --png "sphere-$m-reference.png"
  "$B" render --env builtin:sky:9 --size 128 --brdf "$m" --out "$t/p.exr" --png "sphere-$m-paper.png"
  for c in fractional integer; do
    "$B" render --env builtin:sky:9 --size 128 --brdf "$m" --light-samples 1 --brdf-samples 0 \
      --counts "$c" --out "$t/c.exr" --png "sphere-$m-$c-1spp.png"
  done
done
