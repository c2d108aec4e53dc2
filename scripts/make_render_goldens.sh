#!/usr/bin/env bash
# Rewrites tests/data/goldens/render.json, the committed fingerprints of what the generator
# renders (tests/experiments/golden_render_test.cc): run it on purpose only, when a change to the
# audio or the labels is meant, and say in the commit why the strikes changed.
#
# Usage: scripts/make_render_goldens.sh [BUILD_DIR=build]
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-$ROOT/build}
cmake --build "$BUILD" --target experiments_tests sonicboom -j2
rm -f "$ROOT/tests/data/goldens/render.json"
# the same mode cache as the tests (the build tree's), not the user's
SONICBOOM_CACHE_DIR="$BUILD/test-cache/modes" SONICBOOM_WRITE_RENDER_GOLDENS=1 \
  "$BUILD/bin/experiments_tests" --gtest_filter='Configs/GoldenRenderTest.*'
# and check what was written
SONICBOOM_CACHE_DIR="$BUILD/test-cache/modes" \
  "$BUILD/bin/experiments_tests" --gtest_filter='Configs/GoldenRenderTest.*:GoldenFingerprintTest.*'
