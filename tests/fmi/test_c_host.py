"""The FMUs in a host that is no Python program, as in an FMI tool: a C program loads the FMU's binary with
``dlopen`` (dsg-hil's shim, which loads PythonFMU's binary beside it; libpython preloaded, as docs/how-to/fmi.md
says such a host needs), makes two calls the FMU refuses (fmi2Error, fmi2Discard), runs a step, frees its
instance, unloads the library and ends with exit status 0 (a Python host that leaves its instances to the exit:
``test_host_calls.py``). PythonFMU's binary wrote to freed memory at the end of every such process ("free():
corrupted unsorted chunks", the TCU's FMU: 10 runs in 10); dsg-hil's slaves end the binary's state from Python's
exit, which the binary's own destructor runs (:func:`dsg_hil.fmi.host.end_binary_state_at_exit`). With logging
off the refused call returns fmi2Error all the same, and the host's logger hears nothing."""

from __future__ import annotations

import json
import shutil
import site
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import pytest

from dsg_hil.fmi.export import has_shim

from .test_host_calls import freed_unmapped

CC = shutil.which("cc") or shutil.which("gcc")
LIBPYTHON = Path(str(sysconfig.get_config_var("LIBDIR")), str(sysconfig.get_config_var("INSTSONAME")))
pytestmark = [pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the host is a Linux program"),
              pytest.mark.skipif(CC is None, reason="no C compiler for the host"),
              pytest.mark.skipif(not LIBPYTHON.is_file(), reason=f"no shared libpython ({LIBPYTHON}) to preload")]

HOST = r"""
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct {
    void (*logger)(void*, const char*, int, const char*, const char*, ...);
    void* (*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void*);
    void (*stepFinished)(void*, int);
    void* componentEnvironment;
} Callbacks;

static void logger(void* env, const char* name, int status, const char* category, const char* message, ...) {
    fprintf(stderr, "[%s %d] %s\n", name, status, message);
}

int main(int argc, char** argv) {  /* binary, resource URI, GUID, loggingOn (0 or 1) */
    void* lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "%s\n", dlerror()); return 2; }
    void* (*instantiate)(const char*, int, const char*, const char*, const Callbacks*, int, int) =
        dlsym(lib, "fmi2Instantiate");
    int (*setup)(void*, int, double, double, int, double) = dlsym(lib, "fmi2SetupExperiment");
    int (*enter)(void*) = dlsym(lib, "fmi2EnterInitializationMode");
    int (*leave)(void*) = dlsym(lib, "fmi2ExitInitializationMode");
    int (*set_real)(void*, const unsigned*, size_t, const double*) = dlsym(lib, "fmi2SetReal");
    int (*step)(void*, double, double, int) = dlsym(lib, "fmi2DoStep");
    int (*terminate)(void*) = dlsym(lib, "fmi2Terminate");
    void (*free_instance)(void*) = dlsym(lib, "fmi2FreeInstance");
    static Callbacks callbacks = {logger, calloc, free, NULL, NULL};
    void* c = instantiate("c", 1, argv[3], argv[2], &callbacks, 0, atoi(argv[4]));
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 3; }
    unsigned unknown = 99999;
    double one = 1.0;
    int refused_set = set_real(c, &unknown, 1, &one);
    int refused_step = step(c, 0.0, 0.01, 1);  /* before initialization */
    int s = setup(c, 0, 0.0, 0.0, 0, 0.0), e = enter(c), x = leave(c), t = step(c, 0.0, 0.01, 1);
    printf("{\"refused\": [%d, %d], \"run\": [%d, %d, %d, %d]}\n", refused_set, refused_step, s, e, x, t);
    terminate(c);
    free_instance(c);
    dlclose(lib);  /* PythonFMU's binary stays loaded all the same (STB_GNU_UNIQUE symbols) */
    fflush(stdout);
    return 0;
}
"""


@pytest.fixture(scope="module")
def c_host(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("c_host")
    (folder / "host.c").write_text(HOST, encoding="utf-8")
    subprocess.run([str(CC), "-o", str(folder / "host"), str(folder / "host.c"), "-ldl"], check=True)
    # the embedded interpreter: this Python's standard library, and its site-packages with their .pth files (an
    # editable install's finder)
    (folder / "sitecustomize.py").write_text(
        f"import site\nfor folder in {site.getsitepackages()!r}:\n    site.addsitedir(folder)\n", encoding="utf-8")
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("logging_on", [1, 0])
def test_a_c_host_lives_past_its_exit(c_host, fmus, tmp_path, logging_on):
    with zipfile.ZipFile(fmus["tcu"]) as fmu:
        fmu.extractall(tmp_path)
    root = ElementTree.parse(tmp_path / "modelDescription.xml").getroot()
    binary = tmp_path / "binaries" / "linux64" / f"{root.find('CoSimulation').get('modelIdentifier')}.so"
    env = {**freed_unmapped(), "LD_PRELOAD": str(LIBPYTHON), "PYTHONHOME": sys.base_prefix,
           "PYTHONPATH": str(c_host)}
    done = subprocess.run([str(c_host / "host"), str(binary), (tmp_path / "resources").as_uri(), root.get("guid"),
                           str(logging_on)], capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, f"exit status {done.returncode}; stderr: {done.stderr[-3000:]}"
    out = json.loads(done.stdout.strip().splitlines()[-1])
    refused_set = 3 if has_shim(fmus["tcu"]) else 0  # fmi2Error (dsg-hil's shim); PythonFMU's binary alone: fmi2OK
    assert out == {"refused": [refused_set, 2], "run": [0, 0, 0, 0]}, done.stderr  # and fmi2Discard; then fmi2OK
    named = "value reference 99999" in done.stderr and "fmi2DoStep" in done.stderr
    assert named if logging_on else "[c " not in done.stderr, done.stderr  # logging off: the logger hears nothing
