"""The build backend of csrbf's Python package (PEP 517), in the source tree and on the standard library
alone, so that `pip install .` works offline (pip's isolated build environment needs nothing from PyPI).

build_wheel configures the CMake project (where the build folder is not configured yet), builds the two
extension modules (csrbf._core and csrbf._io) and packs the package directory CMake assembled
(<build>/python/csrbf) into a wheel. The build folder is `build` beside the sources (the README's), or
`--config-settings build-dir=DIR`, or $CSRBF_BUILD_DIR: after the README's build, `pip install .` only
packs. `python3 csrbf_backend.py --pack DIR --out DIST --version V --license FILE` packs without building
(CMake's python_wheel target).
"""

import base64
import hashlib
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]
SUMMARY = "Deformation and interpolation by compactly supported radial basis functions (Wendland CSRBF)"
#: What a wheel takes from the package directory (not __pycache__ or anything else a test left there).
PACKAGED = re.compile(r"^(__init__\.py|_[a-z_]+\.py|_[a-z_]+\.pyi|py\.typed|_(core|io)\..*\.so)$")


class BuildError(Exception):
    """A build that cannot go on, with the reason."""


def _tag() -> str:
    """This interpreter's wheel tag: cp311-cp311-linux_x86_64."""
    version = f"{sys.version_info.major}{sys.version_info.minor}"
    abi = "cp" + version + (sysconfig.get_config_var("abiflags") or "")
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return f"cp{version}-{abi}-{platform}"


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _metadata(version: str) -> str:
    python = f"{sys.version_info.major}.{sys.version_info.minor}"
    return "\n".join([
        "Metadata-Version: 2.1",
        "Name: csrbf",
        f"Version: {version}",
        f"Summary: {SUMMARY}",
        "License: BSD-3-Clause",
        "Classifier: License :: OSI Approved :: BSD License",
        "Classifier: Programming Language :: Python :: 3",
        "Classifier: Topic :: Scientific/Engineering :: Mathematics",
        f"Requires-Python: >={python}",
        "Requires-Dist: numpy>=1.21",
        "License-File: LICENSE",
        "",
    ])


def pack(package_dir: Path, out_dir: Path, version: str, license_file: Path) -> str:
    """Writes the wheel of the built package directory into out_dir (atomically); returns its name."""
    files = sorted(p for p in package_dir.iterdir() if p.is_file() and PACKAGED.match(p.name))
    names = {p.name for p in files}
    for needed in ("__init__.py", "_interpolate.py"):
        if needed not in names:
            raise BuildError(f"{package_dir}: no {needed}: the package was not assembled (build csrbf_python)")
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    for module in ("_core", "_io"):
        if module + suffix not in names:
            built = sorted(n for n in names if n.startswith(module + "."))
            raise BuildError(f"{package_dir}: no {module}{suffix} for this Python ({sys.executable}); found "
                             f"{built or 'none'}: the build folder was configured for another Python")
    name = f"csrbf-{version}-{_tag()}.whl"
    info = f"csrbf-{version}.dist-info"
    entries = [(f"csrbf/{p.name}", p.read_bytes()) for p in files]
    entries += [
        (f"{info}/METADATA", _metadata(version).encode()),
        (f"{info}/WHEEL", f"Wheel-Version: 1.0\nGenerator: csrbf_backend\nRoot-Is-Purelib: false\nTag: {_tag()}\n"
         .encode()),
        (f"{info}/top_level.txt", b"csrbf\n"),
        (f"{info}/LICENSE", license_file.read_bytes()),
    ]
    record = "\n".join(_record_line(n, d) for n, d in entries) + f"\n{info}/RECORD,,\n"
    out_dir.mkdir(parents=True, exist_ok=True)
    partial = out_dir / f".{name}.partial-{os.getpid()}"
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in entries:
            z.writestr(zipfile.ZipInfo(n, date_time=(1980, 1, 1, 0, 0, 0)), d, zipfile.ZIP_DEFLATED)
        z.writestr(zipfile.ZipInfo(f"{info}/RECORD", date_time=(1980, 1, 1, 0, 0, 0)), record, zipfile.ZIP_DEFLATED)
    os.replace(partial, out_dir / name)  # the wheel of this version: a newer build replaces it
    return name


def _version() -> str:
    text = (SOURCE / "CMakeLists.txt").read_text()
    m = re.search(r"project\(csrbf VERSION (\d+\.\d+\.\d+)", text)
    if not m:
        raise BuildError(f"{SOURCE / 'CMakeLists.txt'}: no project(csrbf VERSION x.y.z)")
    return m.group(1)


def _build_dir(config_settings) -> Path:
    given = (config_settings or {}).get("build-dir") or os.environ.get("CSRBF_BUILD_DIR")
    return Path(given).resolve() if given else SOURCE / "build"


def _run(command) -> None:
    # CMake and the compilers run outside pip's isolated environment: Debian's python3 with its numpy.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    print("csrbf_backend:", " ".join(str(c) for c in command), file=sys.stderr, flush=True)
    r = subprocess.run([str(c) for c in command], env=env, stdout=sys.stderr)
    if r.returncode != 0:
        raise BuildError(f"{command[0]} {command[1]} failed (exit {r.returncode}): see its output above")


def _build(build: Path) -> None:
    python = os.path.realpath(getattr(sys, "_base_executable", sys.executable))
    cmake = shutil.which("cmake")
    if cmake is None:
        raise BuildError("cmake not found: run scripts/install-deps.sh (the README's first command)")
    if not (build / "CMakeCache.txt").exists():
        generator = ["-G", "Ninja"] if shutil.which("ninja") else []
        _run([cmake, "-S", SOURCE, "-B", build, *generator, "-DCMAKE_BUILD_TYPE=Release",
              f"-DPython_EXECUTABLE={python}"])
    _run([cmake, "--build", build, "--target", "csrbf_python", "csrbf_python_io", "--parallel",
          str(os.cpu_count() or 1)])


# -- PEP 517 ----------------------------------------------------------------------------------------


def get_requires_for_build_wheel(config_settings=None):
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    build = _build_dir(config_settings)
    _build(build)
    return pack(build / "python" / "csrbf", Path(wheel_directory), _version(), SOURCE / "LICENSE")


def main(argv) -> int:
    import argparse

    parser = argparse.ArgumentParser(description="Packs csrbf's built Python package into a wheel")
    parser.add_argument("--pack", required=True, type=Path, help="the package directory (<build>/python/csrbf)")
    parser.add_argument("--out", required=True, type=Path, help="where the wheel goes")
    parser.add_argument("--version", required=True)
    parser.add_argument("--license", required=True, type=Path)
    args = parser.parse_args(argv)
    try:
        print(pack(args.pack, args.out, args.version, args.license))
    except (BuildError, OSError) as e:
        print(f"csrbf_backend: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
