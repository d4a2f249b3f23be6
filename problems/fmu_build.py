"""Build FMI 2.0 and FMI 3.0 model-exchange FMUs of native problems from C sources.

The sources live beside this module in ``fmu_sources/``: per model a
``modelDescription.xml`` (FMI 2.0), a ``modelDescription3.xml`` (FMI 3.0) and
``sources/<model>.c``, plus the shared function sets ``fmu_common.h`` (FMI 2.0)
and ``fmu_common3.h`` (FMI 3.0), thin wrappers over their version-neutral core
``fmu_core.h`` (value references, modes, FMU state and the logic both
versions share). The model file holds the equations once and includes the header of
the version it is compiled for (preprocessor definition ``FMI_VERSION=3``).
Each FMU of :data:`MODELS` mirrors its native problem (same component names
and order, parameters with the same names and defaults, initial state,
right-hand side, Jacobian and, for ``bouncing_ball``, the impact law as a state
event). The FMI 3.0 models of :data:`FMI3_MODELS` have no native twin: their
array variables (``state_space``) exercise what FMI 3.0 adds.

The build follows the FMI standards' distribution layout (Modelica
Association, "Functional Mock-up Interface for Model Exchange and
Co-Simulation", version 2.0.4, 2022, sect. 2.3; "Functional Mock-up Interface
Specification", version 3.0.1, 2023, sect. 2.5): a zip file with
``modelDescription.xml``, ``sources/`` and
``binaries/<platform>/<modelIdentifier>.so|dll|dylib`` (``linux64`` for FMI 2.0,
``x86_64-linux`` for FMI 3.0). The sources are compiled with fmpy's build
support (:func:`fmpy.build.build_platform_binary`, which drives CMake with
fmpy's ``c-code/CMakeLists.txt``); it takes the source files from
``<SourceFiles>`` of an FMI 2.0 model description and from
``sources/buildDescription.xml`` (FMI 3.0.1 sect. 2.5) of an FMI 3.0 FMU,
which :func:`build_fmu` writes. CMake's progress goes to standard output.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

MODELS = ("spring_pendulum", "two_mass", "bouncing_ball")

#: Models of FMI 3.0 only, without a native twin: ``state_space``, a linear
#: state-space system whose array variables are sized by structural parameters
#: (FMI 3.0 arrays have no FMI 2.0 counterpart).
FMI3_MODELS = ("state_space",)

#: The FMI versions :func:`build_fmu` builds.
FMI_VERSIONS = ("2.0", "3.0")

#: Folder of the model descriptions and C sources.
SOURCE_DIR = pathlib.Path(__file__).resolve().parent / "fmu_sources"

#: The header every model source includes for FMI 2.0 (copied into each FMU's sources/).
COMMON_HEADER = "fmu_common.h"

#: The version-neutral core both versions' headers include (copied into every FMU's sources/).
CORE_HEADER = "fmu_core.h"

#: Per FMI version: the model description in ``SOURCE_DIR/<model>/``, the
#: shared header, and the suffix of the FMU's file name.
_LAYOUT = {"2.0": ("modelDescription.xml", COMMON_HEADER, ""),
           "3.0": ("modelDescription3.xml", "fmu_common3.h", "_fmi3")}

#: ``sources/buildDescription.xml`` of an FMI 3.0 FMU (FMI 3.0.1 sect. 2.5):
#: the model's C file, compiled as C99 with FMI_VERSION=3.
_BUILD_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiBuildDescription fmiVersion="3.0">
  <BuildConfiguration modelIdentifier="{model}">
    <SourceFileSet language="C99">
      <SourceFile name="{model}.c"/>
      <PreprocessorDefinition name="FMI_VERSION" value="3"
        description="selects the FMI 3.0 function set (fmu_common3.h)"/>
    </SourceFileSet>
  </BuildConfiguration>
</fmiBuildDescription>
"""


def search_path() -> str:
    """``PATH`` and then the Python environment's scripts folder: the CMake that
    pip installs with fmpy (``cmake`` on PyPI) serves when the system has none."""
    scripts = str(pathlib.Path(sys.executable).parent)
    return os.pathsep.join(filter(None, [os.environ.get("PATH", ""), scripts]))


@contextlib.contextmanager
def _tools_on_path():
    """``PATH`` set to :func:`search_path` while fmpy runs CMake."""
    saved = os.environ.get("PATH")
    os.environ["PATH"] = search_path()
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("PATH", None)
        else:
            os.environ["PATH"] = saved


def _check_tools() -> None:
    """Raise RuntimeError (one line) when CMake or a C compiler is missing."""
    import fmpy

    path = search_path()
    if shutil.which("cmake", path=path) is None:
        raise RuntimeError("cannot build an FMU: cmake is not installed (not found on PATH "
                           "nor beside Python)")
    if fmpy.system == "windows":       # CMake finds Visual Studio itself
        return
    cc = os.environ.get("CC")
    if cc:
        if shutil.which(cc, path=path) is None:
            raise RuntimeError(f"cannot build an FMU: the C compiler CC={cc!r} is not found")
    elif not any(shutil.which(name, path=path) for name in ("cc", "gcc", "clang")):
        raise RuntimeError("cannot build an FMU: no C compiler (cc, gcc or clang) on PATH")


def build_fmu(model: str, out_dir, fmi_version: str = "2.0",
              source_dir=None) -> pathlib.Path:
    """Build a model-exchange FMU of ``model`` for FMI 2.0 or FMI 3.0.

    FMI 2.0 writes ``<out_dir>/<model>.fmu``, FMI 3.0 ``<out_dir>/<model>_fmi3.fmu``,
    so both can sit in one folder. The FMU's tree (``modelDescription.xml``,
    ``sources/``) is assembled and compiled in a temporary directory; only the
    finished ``.fmu`` is written into ``out_dir`` (created if missing; an
    existing file is replaced).

    Parameters
    ----------
    model : str
        One of :data:`MODELS`, or of :data:`FMI3_MODELS` for FMI 3.0.
    out_dir : str or os.PathLike
        Folder to write the FMU into.
    fmi_version : str, optional
        One of :data:`FMI_VERSIONS`, ``"2.0"`` (the default) or ``"3.0"``.
    source_dir : str or os.PathLike, optional
        A folder laid out as ``SOURCE_DIR/<model>`` (the model description and
        ``sources/<model>.c``, including the shared headers as the project's
        models do) for a model of one's own; then ``model`` is any name.

    Returns
    -------
    pathlib.Path
        The absolute path of the FMU.

    Raises
    ------
    ValueError
        If ``model`` is not one of :data:`MODELS` or :data:`FMI3_MODELS` (without
        ``source_dir``), ``fmi_version`` not one of :data:`FMI_VERSIONS`, or a
        model of :data:`FMI3_MODELS` is asked for FMI 2.0.
    RuntimeError
        If CMake or a C compiler is missing, or the compilation fails.

    Notes
    -----
    The archive holds ``modelDescription.xml`` (for FMI 3.0 a copy of
    ``modelDescription3.xml``), ``sources/`` (the model's C file, the
    version's shared header, :data:`CORE_HEADER` and, for FMI 3.0,
    ``buildDescription.xml``) and
    ``binaries/<platform>/``, as the FMI 2.0.4 standard, sect. 2.3, and the
    FMI 3.0.1 standard, sect. 2.5, lay out; it is zipped with
    :func:`fmpy.util.create_zip_archive`.
    """
    if source_dir is None and model not in MODELS + FMI3_MODELS:
        raise ValueError(f"unknown FMU model {model!r}; valid choices: "
                         f"{', '.join(MODELS + FMI3_MODELS)}")
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"unknown FMI version {fmi_version!r}; valid choices: "
                         f"{', '.join(FMI_VERSIONS)}")
    if source_dir is None and model in FMI3_MODELS and fmi_version != "3.0":
        raise ValueError(f"FMU model {model!r} has array variables, which only FMI 3.0 "
                         "has; build it with fmi_version='3.0'")
    _check_tools()
    from fmpy.build import build_platform_binary
    from fmpy.util import create_zip_archive

    description, header, suffix = _LAYOUT[fmi_version]
    out_dir = pathlib.Path(out_dir).resolve()
    with tempfile.TemporaryDirectory(prefix=f"fmu_{model}_") as tmp:
        tmp = pathlib.Path(tmp).resolve()
        tree, build = tmp / model, tmp / "build"
        build.mkdir()
        model_dir = SOURCE_DIR / model if source_dir is None else pathlib.Path(source_dir)
        shutil.copytree(model_dir / "sources", tree / "sources")
        shutil.copy2(model_dir / description, tree / "modelDescription.xml")
        for name in (header, CORE_HEADER):
            shutil.copy2(SOURCE_DIR / name, tree / "sources" / name)
        if fmi_version == "3.0":
            (tree / "sources" / "buildDescription.xml").write_text(
                _BUILD_DESCRIPTION.format(model=model), encoding="utf-8")
        try:
            with _tools_on_path():
                build_platform_binary(tree, build_dir=build)
        except (subprocess.CalledProcessError, OSError) as exc:
            raise RuntimeError(f"building the FMU {model!r} (FMI {fmi_version}) failed: "
                               f"{exc}") from exc
        archive = tmp / f"{model}{suffix}.fmu"
        create_zip_archive(archive, tree)
        out_dir.mkdir(parents=True, exist_ok=True)
        target = out_dir / archive.name
        shutil.move(str(archive), str(target))
    return target
