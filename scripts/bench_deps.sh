#!/usr/bin/env bash
# Installs what the benchmark scripts need: everything scripts/install_deps.sh
# installs, plus matplotlib for scripts/bench_plot.py (Debian's, run with
# /usr/bin/python3). Skips what is already present.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
if ! dpkg-query -W -f='${Status}' python3-matplotlib 2>/dev/null | grep -q "install ok installed"; then
  echo "installing: python3-matplotlib"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends python3-matplotlib >/dev/null
fi
