/* A minimal FMI 3.0 co-simulation host: the FMI 3.0 twin of host.c (same arguments, same output),
 * built for Linux (gcc, dlopen) and for Windows (mingw, LoadLibrary), so that
 * tests/python/test_fmi3.py runs the same sequence of calls on binaries/x86_64-linux/<id>.so
 * natively and on binaries/x86_64-windows/<id>.dll under wine and compares the printed numbers
 * with each other and with the FMI 2.0 host's.
 *
 *   host3 LIBRARY MODEL_ID TOKEN STEPS H INPUTS OUTPUTS [vr=value ...]
 *
 * INPUTS: "vrA,vrS" = value references of crank.angle and crank.speed (set every step to
 * omega*t and omega, omega = the start value of crank.speed as read back), or "-" for none.
 * OUTPUTS: comma-separated value references printed after every step as %.17g.
 * vr=value: Float64 parameters set in initialization mode (vr:i=value Int32, vr:b=0|1 Boolean).
 */
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../c/fmu_load.h"

typedef void *I;
typedef void (*LogMessage)(void *, int, const char *, const char *);

static void log_message(void *env, int status, const char *cat, const char *msg) {
    (void)env; (void)cat;
    fprintf(stderr, "[%d] %s\n", status, msg);
}

typedef I (*Instantiate)(const char *, const char *, const char *, bool, bool, bool, bool,
                         const unsigned *, size_t, void *, LogMessage, void *);
typedef int (*Enter)(I, bool, double, double, bool, double);
typedef int (*Mode)(I);
typedef int (*SetF64)(I, const unsigned *, size_t, const double *, size_t);
typedef int (*SetI32)(I, const unsigned *, size_t, const int *, size_t);
typedef int (*SetBool)(I, const unsigned *, size_t, const bool *, size_t);
typedef int (*GetF64)(I, const unsigned *, size_t, double *, size_t);
typedef int (*DoStep)(I, double, double, bool, bool *, bool *, bool *, double *);
typedef void (*Free)(I);

int main(int argc, char **argv) {
    if (argc < 8) { fprintf(stderr, "usage: host3 LIB ID TOKEN STEPS H INPUTS OUTPUTS [vr=value...]\n"); return 2; }
    void *lib = fmu_load(argv[1]);
    if (!lib) { fprintf(stderr, "cannot load %s\n", argv[1]); return 3; }
    Instantiate inst = (Instantiate)fmu_sym(lib, "fmi3InstantiateCoSimulation");
    Enter enter = (Enter)fmu_sym(lib, "fmi3EnterInitializationMode");
    Mode exit_ = (Mode)fmu_sym(lib, "fmi3ExitInitializationMode");
    SetF64 setr = (SetF64)fmu_sym(lib, "fmi3SetFloat64");
    SetI32 seti = (SetI32)fmu_sym(lib, "fmi3SetInt32");
    SetBool setb = (SetBool)fmu_sym(lib, "fmi3SetBoolean");
    GetF64 getr = (GetF64)fmu_sym(lib, "fmi3GetFloat64");
    DoStep step = (DoStep)fmu_sym(lib, "fmi3DoStep");
    Free freei = (Free)fmu_sym(lib, "fmi3FreeInstance");
    if (!inst || !enter || !exit_ || !setr || !seti || !setb || !getr || !step || !freei) { fprintf(stderr, "missing export\n"); return 3; }
    I c = inst(argv[2], argv[3], NULL, false, false, false, false, NULL, 0, NULL, log_message, NULL);
    if (!c) { fprintf(stderr, "fmi3InstantiateCoSimulation failed\n"); return 4; }
    int steps = atoi(argv[4]);
    double h = atof(argv[5]);
    unsigned in[2], out[256];
    int nin = strcmp(argv[6], "-") ? fmu_parse_vrs(argv[6], in, 2) : 0;
    int nout = fmu_parse_vrs(argv[7], out, 256);
    if (enter(c, false, 0.0, 0.0, false, 0.0)) return 5;
    for (int i = 8; i < argc; i++) {
        char *eq = strchr(argv[i], '=');
        if (!eq) return 2;
        unsigned vr = (unsigned)strtoul(argv[i], NULL, 10);
        if (strstr(argv[i], ":i=")) { int v = atoi(eq + 1); if (seti(c, &vr, 1, &v, 1)) return 6; }
        else if (strstr(argv[i], ":b=")) { bool v = atoi(eq + 1) != 0; if (setb(c, &vr, 1, &v, 1)) return 6; }
        else { double v = strtod(eq + 1, NULL); if (setr(c, &vr, 1, &v, 1)) return 6; }
    }
    if (exit_(c)) return 7;
    double omega = 0.0, vals[256];
    if (nin == 2 && getr(c, &in[1], 1, &omega, 1)) return 8;
    for (int k = 0; k <= steps; k++) {
        double t = k * h;
        if (nin == 2) { double x[2] = {omega * t, omega}; if (setr(c, in, 2, x, 2)) return 9; }
        if (getr(c, out, (size_t)nout, vals, (size_t)nout)) return 10;
        for (int j = 0; j < nout; j++) printf(j ? ",%.17g" : "%.17g", vals[j]);
        printf("\n");
        bool event, terminate, early;
        double last;
        if (k < steps && step(c, t, h, true, &event, &terminate, &early, &last)) return 11;
        if (k < steps && (event || terminate || early || last != t + h)) { fprintf(stderr, "doStep flags\n"); return 12; }
    }
    freei(c);
    return 0;
}
