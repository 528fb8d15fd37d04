/* The loading code of the C hosts (tests/win64/host.c and host3.c, benches/c/host_loop.c,
 * me_eval.c and directional.c), written once: a shared object opened as an importer opens it
 * (dlopen with RTLD_NOW | RTLD_LOCAL on Linux, LoadLibraryA on Windows), its functions looked up
 * by name, and the value-reference lists of their command lines parsed. Header only (inline
 * functions), so that each host stays one file to compile, natively, with mingw and for aarch64.
 */
#ifndef RD_FMU_LOAD_H
#define RD_FMU_LOAD_H

#include <stdio.h>
#include <stdlib.h>
#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif

/* The shared object at `path`, or NULL when it cannot be loaded (fmu_load_error says why). */
static inline void *fmu_load(const char *path) {
#ifdef _WIN32
    return (void *)LoadLibraryA(path);
#else
    return dlopen(path, RTLD_NOW | RTLD_LOCAL);
#endif
}

/* Why the last fmu_load failed. */
static inline const char *fmu_load_error(void) {
#ifdef _WIN32
    return "LoadLibrary failed";
#else
    const char *e = dlerror();
    return e ? e : "dlopen failed";
#endif
}

/* The function `name` of `lib`, or NULL when it does not export it. */
static inline void *fmu_sym(void *lib, const char *name) {
#ifdef _WIN32
    return (void *)GetProcAddress((HMODULE)lib, name);
#else
    return dlsym(lib, name);
#endif
}

/* The function `name` of `lib`; a missing one ends the host with status 2 and one line naming it. */
static inline void *fmu_need(void *lib, const char *name) {
    void *p = fmu_sym(lib, name);
    if (!p) { fprintf(stderr, "missing %s\n", name); exit(2); }
    return p;
}

/* A comma-separated list of value references ("3,4,17") into `out` (at most `max`); their number. */
static inline int fmu_parse_vrs(const char *s, unsigned *out, int max) {
    int n = 0;
    while (*s && n < max) {
        out[n++] = (unsigned)strtoul(s, (char **)&s, 10);
        if (*s == ',') s++;
    }
    return n;
}

#endif
