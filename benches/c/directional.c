/* Host of scripts/bench_directional.py: loads an FMI 2.0 co-simulation FMU's shared object with
 * dlopen, as an importer does, and per iteration sets the 3 crank inputs (angle advancing by
 * SPEED*1ms, speed, acceleration) and then either reads one output (fmi2GetReal) or asks for one
 * directional derivative of it (fmi2GetDirectionalDerivative, seed 1 on one known). Run under
 * callgrind, the inclusive instructions of fmi2GetReal and fmi2GetDirectionalDerivative per call
 * compare the two. Written for this project.
 *
 * usage: directional FMU.so GUID IN OUT KNOWN MODE SPEED N [SET...]
 *   IN: comma-separated value references of (angle, speed, acceleration); OUT: the output;
 *   KNOWN: the known of the derivative; MODE: "value" or "derivative";
 *   SET: r:VR=VALUE, i:VR=VALUE or b:VR=VALUE, set in initialization mode. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "../../tests/c/fmu_load.h"

static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c,
                   fmi2String m, ...) {
    (void)e; (void)n; (void)c;
    if (s != fmi2OK) fprintf(stderr, "%s\n", m);
}

int main(int argc, char **argv) {
    if (argc < 9) { fprintf(stderr, "usage: see the source\n"); return 2; }
    void *lib = fmu_load(argv[1]);
    if (!lib) { fprintf(stderr, "%s\n", fmu_load_error()); return 2; }
    fmi2InstantiateTYPE *instantiate = fmu_need(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = fmu_need(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter = fmu_need(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *exit_init = fmu_need(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = fmu_need(lib, "fmi2SetReal");
    fmi2SetIntegerTYPE *set_integer = fmu_need(lib, "fmi2SetInteger");
    fmi2SetBooleanTYPE *set_boolean = fmu_need(lib, "fmi2SetBoolean");
    fmi2GetRealTYPE *get_real = fmu_need(lib, "fmi2GetReal");
    fmi2GetDirectionalDerivativeTYPE *dd = fmu_need(lib, "fmi2GetDirectionalDerivative");
    fmi2FreeInstanceTYPE *free_instance = fmu_need(lib, "fmi2FreeInstance");
    fmi2ValueReference in[3];
    if (sscanf(argv[3], "%u,%u,%u", &in[0], &in[1], &in[2]) != 3) return 2;
    fmi2ValueReference out = (fmi2ValueReference)strtoul(argv[4], NULL, 10);
    fmi2ValueReference known = (fmi2ValueReference)strtoul(argv[5], NULL, 10);
    int derivative = strcmp(argv[6], "derivative") == 0;
    double speed = strtod(argv[7], NULL);
    long n = strtol(argv[8], NULL, 10);
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("bench", fmi2CoSimulation, argv[2], "", &cb, fmi2False, fmi2False);
    if (!c) return 1;
    setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    enter(c);
    for (int i = 9; i < argc; i++) {
        char kind;
        unsigned vr;
        double v;
        if (sscanf(argv[i], "%c:%u=%lf", &kind, &vr, &v) != 3) return 2;
        fmi2ValueReference r = vr;
        if (kind == 'r') set_real(c, &r, 1, &v);
        else if (kind == 'i') { fmi2Integer x = (fmi2Integer)v; set_integer(c, &r, 1, &x); }
        else { fmi2Boolean x = v != 0.0; set_boolean(c, &r, 1, &x); }
    }
    if (exit_init(c) != fmi2OK) return 1;
    double sum = 0.0, seed = 1.0;
    for (long k = 0; k < n; k++) {
        double x[3] = {speed * 1e-3 * (double)k, speed, 0.5};
        set_real(c, in, 3, x);
        double y = 0.0;
        fmi2Status st = derivative ? dd(c, &out, 1, &known, 1, &seed, &y) : get_real(c, &out, 1, &y);
        if (st != fmi2OK) return 1;
        sum += y;
    }
    printf("%.17g\n", sum);
    free_instance(c);
    return 0;
}
