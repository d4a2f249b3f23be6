"""Build FMI 2.0 model-exchange FMUs of native problems from their C sources.

The sources live beside this module in ``fmu_sources/``: per model a
``modelDescription.xml`` and ``sources/<model>.c``, plus the shared
``fmu_common.h`` (the FMI 2.0 function set; value references, modes and FMU
state). Each FMU mirrors its native problem (same component names and order,
parameters with the same names and defaults, initial state, right-hand side,
Jacobian and, for ``bouncing_ball``, the impact law as a state event).

The build follows the FMI 2.0.4 standard (Modelica Association, "Functional
Mock-up Interface for Model Exchange and Co-Simulation", version 2.0.4, 2022),
sect. 2.3 (FMU distribution: a zip file with ``modelDescription.xml``,
``sources/`` and ``binaries/<platform>/<modelIdentifier>.so|dll|dylib``), and
compiles the sources named in ``<SourceFiles>`` with fmpy's build support
(:func:`fmpy.build.build_platform_binary`, which drives CMake with fmpy's
``c-code/CMakeLists.txt``). CMake's progress goes to standard output.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import tempfile

MODELS = ("spring_pendulum", "two_mass", "bouncing_ball")

#: Folder of the model descriptions and C sources.
SOURCE_DIR = pathlib.Path(__file__).resolve().parent / "fmu_sources"

#: The header every model source includes (copied into each FMU's sources/).
COMMON_HEADER = "fmu_common.h"


def _check_tools() -> None:
    """Raise RuntimeError (one line) when CMake or a C compiler is missing."""
    import fmpy

    if shutil.which("cmake") is None:
        raise RuntimeError("cannot build an FMU: cmake is not installed (not found on PATH)")
    if fmpy.system == "windows":       # CMake finds Visual Studio itself
        return
    cc = os.environ.get("CC")
    if cc:
        if shutil.which(cc) is None:
            raise RuntimeError(f"cannot build an FMU: the C compiler CC={cc!r} is not found")
    elif not any(shutil.which(name) for name in ("cc", "gcc", "clang")):
        raise RuntimeError("cannot build an FMU: no C compiler (cc, gcc or clang) on PATH")


def build_fmu(model: str, out_dir) -> pathlib.Path:
    """Build ``<out_dir>/<model>.fmu``, an FMI 2.0 model-exchange FMU.

    The FMU's tree (``modelDescription.xml``, ``sources/``) is assembled and
    compiled in a temporary directory; only the finished ``.fmu`` is written
    into ``out_dir`` (created if missing; an existing file is replaced).

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    out_dir : str or os.PathLike
        Folder to write the FMU into.

    Returns
    -------
    pathlib.Path
        The absolute path of the FMU.

    Raises
    ------
    ValueError
        If ``model`` is not one of :data:`MODELS`.
    RuntimeError
        If CMake or a C compiler is missing, or the compilation fails.

    Notes
    -----
    The archive holds ``modelDescription.xml``, ``sources/`` (the model's C
    file and ``fmu_common.h``) and ``binaries/<platform>/`` as the FMI 2.0.4
    standard, sect. 2.3, lays out; it is zipped with
    :func:`fmpy.util.create_zip_archive`.
    """
    if model not in MODELS:
        raise ValueError(f"unknown FMU model {model!r}; valid choices: {', '.join(MODELS)}")
    _check_tools()
    from fmpy.build import build_platform_binary
    from fmpy.util import create_zip_archive

    out_dir = pathlib.Path(out_dir).resolve()
    with tempfile.TemporaryDirectory(prefix=f"fmu_{model}_") as tmp:
        tmp = pathlib.Path(tmp).resolve()
        tree, build = tmp / model, tmp / "build"
        build.mkdir()
        shutil.copytree(SOURCE_DIR / model, tree)
        shutil.copy2(SOURCE_DIR / COMMON_HEADER, tree / "sources" / COMMON_HEADER)
        try:
            build_platform_binary(tree, build_dir=build)
        except (subprocess.CalledProcessError, OSError) as exc:
            raise RuntimeError(f"building the FMU {model!r} failed: {exc}") from exc
        archive = tmp / f"{model}.fmu"
        create_zip_archive(archive, tree)
        out_dir.mkdir(parents=True, exist_ok=True)
        target = out_dir / f"{model}.fmu"
        shutil.move(str(archive), str(target))
    return target
