/* A minimal FMI 2.0 co-simulation host, built for Linux (gcc, dlopen) and for Windows (mingw,
 * LoadLibrary) from this one file, so that tests/python/test_win64.py can run the same sequence
 * of calls on binaries/linux64/<id>.so natively and on binaries/win64/<id>.dll under wine and
 * compare the printed numbers.
 *
 *   host LIBRARY MODEL_ID GUID STEPS H INPUTS OUTPUTS [vr=value ...]
 *
 * INPUTS: "vrA,vrS" = value references of crank.angle and crank.speed (set every step to
 * omega*t and omega, omega = the start value of crank.speed as read back), or "-" for none.
 * OUTPUTS: comma-separated value references printed after every step as %.17g.
 * vr=value: Real parameters set in initialization mode (vr:i=value Integer, vr:b=0|1 Boolean).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdarg.h>
#include "../c/fmu_load.h"

typedef void *C;
typedef struct {
    void (*logger)(void *, const char *, int, const char *, const char *, ...);
    void *(*allocate)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *env;
} Callbacks;

static void logger(void *env, const char *name, int status, const char *cat, const char *msg, ...) {
    (void)env; (void)name; (void)cat;
    va_list ap;
    va_start(ap, msg);
    fprintf(stderr, "[%d] ", status);
    vfprintf(stderr, msg, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

typedef C (*Instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int);
typedef int (*Setup)(C, int, double, double, int, double);
typedef int (*Mode)(C);
typedef int (*SetReal)(C, const unsigned *, size_t, const double *);
typedef int (*SetInt)(C, const unsigned *, size_t, const int *);
typedef int (*GetReal)(C, const unsigned *, size_t, double *);
typedef int (*DoStep)(C, double, double, int);
typedef void (*Free)(C);

int main(int argc, char **argv) {
    if (argc < 8) { fprintf(stderr, "usage: host LIB ID GUID STEPS H INPUTS OUTPUTS [vr=value...]\n"); return 2; }
    void *lib = fmu_load(argv[1]);
    if (!lib) { fprintf(stderr, "cannot load %s\n", argv[1]); return 3; }
    Instantiate inst = (Instantiate)fmu_sym(lib, "fmi2Instantiate");
    Setup setup = (Setup)fmu_sym(lib, "fmi2SetupExperiment");
    Mode enter = (Mode)fmu_sym(lib, "fmi2EnterInitializationMode"), exit_ = (Mode)fmu_sym(lib, "fmi2ExitInitializationMode");
    SetReal setr = (SetReal)fmu_sym(lib, "fmi2SetReal");
    SetInt seti = (SetInt)fmu_sym(lib, "fmi2SetInteger");
    SetInt setb = (SetInt)fmu_sym(lib, "fmi2SetBoolean");
    GetReal getr = (GetReal)fmu_sym(lib, "fmi2GetReal");
    DoStep step = (DoStep)fmu_sym(lib, "fmi2DoStep");
    Free freei = (Free)fmu_sym(lib, "fmi2FreeInstance");
    if (!inst || !setup || !enter || !exit_ || !setr || !seti || !setb || !getr || !step || !freei) { fprintf(stderr, "missing export\n"); return 3; }
    Callbacks cb = {logger, NULL, NULL, NULL, NULL};
    C c = inst(argv[2], 1 /* fmi2CoSimulation */, argv[3], NULL, &cb, 0, 0);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
    int steps = atoi(argv[4]);
    double h = atof(argv[5]);
    unsigned in[2], out[256];
    int nin = strcmp(argv[6], "-") ? fmu_parse_vrs(argv[6], in, 2) : 0;
    int nout = fmu_parse_vrs(argv[7], out, 256);
    if (setup(c, 0, 0.0, 0.0, 0, 0.0) || enter(c)) return 5;
    for (int i = 8; i < argc; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq) return 2;
        unsigned vr = (unsigned)strtoul(argv[i], NULL, 10);
        if (strstr(argv[i], ":i=")) { int v = atoi(eq + 1); if (seti(c, &vr, 1, &v)) return 6; }
        else if (strstr(argv[i], ":b=")) { int v = atoi(eq + 1); if (setb(c, &vr, 1, &v)) return 6; }
        else { double v = strtod(eq + 1, NULL); if (setr(c, &vr, 1, &v)) return 6; }
    }
    if (exit_(c)) return 7;
    double omega = 0.0, vals[256];
    if (nin == 2 && getr(c, &in[1], 1, &omega)) return 8;
    for (int k = 0; k <= steps; k++) {
        double t = k * h;
        if (nin == 2) { double x[2] = {omega * t, omega}; if (setr(c, in, 2, x)) return 9; }
        if (getr(c, out, (size_t)nout, vals)) return 10;
        for (int j = 0; j < nout; j++) printf(j ? ",%.17g" : "%.17g", vals[j]);
        printf("\n");
        if (k < steps && step(c, t, h, 1)) return 11;
    }
    freei(c);
    return 0;
}
