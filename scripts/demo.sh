#!/bin/sh
# Install what is missing, build, and run `kogei demo` on the bundled default.
# Idempotent. Output goes to out/demo/ unless KOGEI_DEMO_OUT says otherwise.
set -eu
cd "$(dirname "$0")/.."
./scripts/setup.sh
if [ -f build/build.ninja ]; then
	meson setup --reconfigure build >/dev/null
else
	meson setup build
fi
ninja -C build
exec ./build/cli/kogei demo -o "${KOGEI_DEMO_OUT:-out/demo}"
