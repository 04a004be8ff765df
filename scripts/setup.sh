#!/bin/sh
# Install the Debian 12 packages kogei builds and tests with. Idempotent: asks apt
# only for what is missing, so a second run does nothing and needs no network.
set -eu

PACKAGES="
build-essential meson ninja-build pkg-config
liblapacke-dev libtiff-dev libpng-dev libjansson-dev zlib1g-dev libcairo2-dev fonts-dejavu-core libssl-dev libjpeg-dev
colord-data argyll argyll-ref
python3 python3-numpy python3-spectral
libapriltag-dev libopencv-dev libopencv-contrib-dev
libusb-1.0-0-dev umockdev libumockdev-dev
libaravis-dev aravis-tools aravis-tools-cli libcamera-dev
libembree-dev assimp-testmodels iproute2 util-linux strace
chromium python3-websocket
libraw-dev libgphoto2-dev libmicrohttpd-dev
liblcms2-dev liblcms2-utils imagemagick
libxml2-utils libimage-exiftool-perl
slurmctld slurmd slurm-client munge
blender
libvips-dev libvips-tools iipimage-server lighttpd
"
# Node.js and npm (for the glTF validator below) from Debian unless a node and npm are
# already on the machine (a nodejs package that brings its own npm conflicts with
# Debian's npm package).
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
	PACKAGES="$PACKAGES nodejs npm"
fi

missing=""
for p in $PACKAGES; do
	if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
		missing="$missing $p"
	fi
done

if [ -n "$missing" ]; then
	echo "setup: installing:$missing"
	if [ "$(id -u)" != 0 ]; then
		echo "setup: need root to install packages (run as root or with sudo)" >&2
		exit 1
	fi
	export DEBIAN_FRONTEND=noninteractive
	apt-get update -qq
	# shellcheck disable=SC2086
	apt-get install -y -qq --no-install-recommends $missing
else
	echo "setup: all packages present"
fi

# The Khronos glTF-Validator (npm package gltf-validator), for the gltf-validator test:
# into the project's own .tools folder, only when it is not there yet.
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VALIDATOR="$ROOT/.tools/gltf-validator"
if [ -f "$VALIDATOR/node_modules/gltf-validator/package.json" ]; then
	echo "setup: gltf-validator present"
elif command -v npm >/dev/null 2>&1; then
	echo "setup: installing gltf-validator into $VALIDATOR"
	mkdir -p "$VALIDATOR"
	npm install --silent --no-audit --no-fund --prefix "$VALIDATOR" gltf-validator@2.0.0-dev.3.10
else
	echo "setup: npm not found: gltf-validator not installed (the gltf-validator test skips)" >&2
fi

# OpenSeadragon (npm package openseadragon), the viewer the IIIF test opens the
# manifests in: into .tools/openseadragon, only when it is not there yet.
OSD="$ROOT/.tools/openseadragon"
if [ -f "$OSD/node_modules/openseadragon/package.json" ]; then
	echo "setup: openseadragon present"
elif command -v npm >/dev/null 2>&1; then
	echo "setup: installing openseadragon into $OSD"
	mkdir -p "$OSD"
	npm install --silent --no-audit --no-fund --prefix "$OSD" openseadragon@4.1.1
else
	echo "setup: npm not found: openseadragon not installed (the IIIF viewer test skips)" >&2
fi
