#!/usr/bin/env bash
# System packages the tests need beyond Python wheels, installed once per machine (CI runs this).
#   ffmpeg    - torchcodec (lerobot's video decoder) loads Debian's ffmpeg libraries.
#   chromium  - headless browser for the web-page tests (driven by Playwright, never downloaded).
# npm packages for the browser tests come from package.json at the repository root (npm ci).
set -euo pipefail
cd "$(dirname "$0")/.."
need=()
command -v ffmpeg >/dev/null 2>&1 || need+=(ffmpeg)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
if [ ${#need[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "installing Debian packages: ${need[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
if [ -f package.json ] && command -v npm >/dev/null 2>&1; then
  if [ ! -d node_modules ] || [ package-lock.json -nt node_modules ]; then
    npm ci --no-audit --no-fund --silent
  fi
fi
