#!/usr/bin/env bash
# Installs the Debian packages dicer needs (skips those already present).
# The last two lines are independent readers used by the interop tests:
# h5dump with the HDF Group's LZ4 plugin, h5py with hdf5plugin, VTK's
# vtkHDFReader, meshio (with netCDF4 for Exodus) and Gmsh's Python API.
# Then the Python package (pybind11, for Debian's /usr/bin/python3), its
# pytest suite, the pictures (matplotlib) and the finite-element solver
# the Poisson example and test use (DOLFINx 0.5.2 with petsc4py); scipy
# and petsc4py also read the transfer operators (the two-grid example);
# help2man writes the man pages, which man-db and bash-completion check.
# Arguments: more packages to install with them.
set -euo pipefail
pkgs=(cmake g++ make pkg-config libhdf5-dev liblz4-dev libdeflate-dev libexodusii-dev libnetcdf-dev libgmsh-dev
      libgtest-dev libbenchmark-dev nlohmann-json3-dev libcli11-dev
      libopenmpi-dev openmpi-bin libhdf5-openmpi-dev libnetcdf-mpi-dev
      hdf5-tools hdf5-filter-plugin python3-h5py python3-hdf5plugin
      python3-vtk9 python3-meshio python3-netcdf4 python3-gmsh
      pybind11-dev python3-dev python3-numpy python3-pytest python3-mpi4py python3-matplotlib
      python3-dolfinx python3-petsc4py python3-scipy
      help2man man-db groff-base bash-completion
      "$@")  # more on request (run_tests.sh: ccache, clang)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
