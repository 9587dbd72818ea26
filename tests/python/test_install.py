"""`cmake --install` puts the package where Debian's python3 finds it, and the
installed package works without the build tree (dicer-cad found beside it)."""
import os
import subprocess
import sys

import pytest

from conftest import DATA, EXAMPLES


def clean_env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "DICER_CAD")}
    env.update(extra)
    return env


def test_the_install_dir_is_on_debian_pythons_path():
    prefix, rel = os.environ["DICER_INSTALL_PREFIX"], os.environ["DICER_PYTHON_INSTALL_DIR"]
    out = subprocess.run(["/usr/bin/python3", "-c", "import sys; print('\\n'.join(sys.path))"], env=clean_env(),
                         capture_output=True, text=True, check=True, cwd="/")
    assert os.path.join(prefix, rel) in out.stdout.splitlines(), out.stdout


def test_installed_package_works_alone(tmp_path):
    build = os.environ["DICER_BUILD_DIR"]
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", build, "--prefix", str(prefix)], check=True, capture_output=True)
    site = prefix / os.environ["DICER_PYTHON_INSTALL_DIR"]
    assert (site / "dicer" / "__init__.py").exists()
    script = (
        "import dicer, sys\n"
        "assert dicer.__file__.startswith(sys.argv[1]), dicer.__file__\n"
        f"s = dicer.dice({str(DATA / 'cardinal_sphere.e')!r}, 'a.dice.h5', interval=2)\n"
        "assert s.num_elements == 256 * 8\n"
        f"m = dicer.mesh_coarse({str(EXAMPLES / 'cylinder.brep')!r}, 'c.msh', size=0.8)\n"
        f"g = dicer.dice(m, 'g.dice.h5', interval=1, geometry={str(EXAMPLES / 'cylinder.brep')!r})\n"
        "print(g.num_elements)\n")
    out = subprocess.run([sys.executable, "-c", script, str(prefix)], env=clean_env(PYTHONPATH=str(site)),
                         capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) > 0
