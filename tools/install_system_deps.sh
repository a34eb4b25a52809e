#!/usr/bin/env bash
# What the tests need beyond Python wheels, installed once per machine; `make test` runs this first,
# and it does nothing when everything is already there.
#   Debian packages:
#     ffmpeg          - torchcodec (lerobot's video decoder) loads Debian's ffmpeg libraries.
#     chromium        - headless browser for the web-page tests (driven by Playwright, never downloaded).
#     nodejs, npm     - to install the npm packages below.
#   npm packages (package.json at the repository root, `npm ci`): iwer, the WebXR emulator.
# Debian packages need root: run as root, or as a user with sudo. Without either it stops at once and
# names the one command that installs them.
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
command -v ffmpeg >/dev/null 2>&1 || need+=(ffmpeg)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
command -v node >/dev/null 2>&1 || need+=(nodejs)
command -v npm >/dev/null 2>&1 || need+=(npm)

if [ ${#need[@]} -gt 0 ]; then
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    if ! command -v sudo >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
      echo "error: the tests need the Debian packages: ${need[*]}" >&2
      echo "and installing them needs root (or sudo) and apt-get. Run once, as root:" >&2
      echo "    apt-get update && apt-get install -y --no-install-recommends ${need[*]}" >&2
      exit 1
    fi
    sudo="sudo"
  elif ! command -v apt-get >/dev/null 2>&1; then
    echo "error: the tests need the Debian packages: ${need[*]}, and apt-get is missing." >&2
    echo "Install them with this system's package manager, then run make test again." >&2
    exit 1
  fi
  echo "installing Debian packages: ${need[*]}"
  start=$SECONDS
  $sudo apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  echo "installed ${need[*]} in $((SECONDS - start)) s"
fi

# Reinstall the npm packages when the lock changed since the last install.
if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
  echo "installing npm packages (npm ci)"
  npm ci --no-audit --no-fund --silent
fi
