/* Native host of scripts/bench_me.py: Model Exchange evaluation of the FMU against its
 * co-simulation loop, both through one dlopen'ed shared object (it carries both interfaces), in
 * alternating runs so that both see the same machine state. Per time point t = k*h:
 *   cs:   fmi2SetReal of the 3 crank inputs, fmi2DoStep (h), fmi2GetReal of N outputs
 *         (the co-simulation loop of scripts/bench_ratio.py)
 *   me:   fmi2SetTime, fmi2SetReal of the 3 crank inputs, fmi2GetReal of the N outputs
 *         (a solver's evaluation of a mechanism without states: the outputs it asks for)
 *   rhs:  fmi2SetTime, fmi2SetReal of the inputs, fmi2SetContinuousStates, fmi2GetDerivatives,
 *         fmi2GetReal of the N outputs (the full right-hand side evaluation of a solver that
 *         integrates the FMU's declared states)
 * It prints the median ns per time point of each over ROUNDS runs. Written for this project.
 * Environment: ME_EVAL_ONLY = cs, me or rhs runs that mode alone (for callgrind's counts).
 *
 * usage: me_eval FMU.so GUID IN OUT NX SPEED H STEPS ROUNDS [SET...]
 *   IN, OUT: comma-separated value references (3 crank inputs; the outputs read)
 *   NX: the FMU's number of continuous states
 *   SET: r:VR=VALUE, i:VR=VALUE or b:VR=VALUE, set in initialization mode */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"
#include "../../tests/c/fmu_load.h"

static fmi2InstantiateTYPE *instantiate;
static fmi2FreeInstanceTYPE *free_instance;
static fmi2SetupExperimentTYPE *setup;
static fmi2EnterInitializationModeTYPE *enter;
static fmi2ExitInitializationModeTYPE *exit_init;
static fmi2SetRealTYPE *set_real;
static fmi2SetIntegerTYPE *set_integer;
static fmi2SetBooleanTYPE *set_boolean;
static fmi2GetRealTYPE *get_real;
static fmi2DoStepTYPE *do_step;
static fmi2SetTimeTYPE *set_time;
static fmi2NewDiscreteStatesTYPE *new_discrete_states;
static fmi2EnterContinuousTimeModeTYPE *enter_ct;
static fmi2SetContinuousStatesTYPE *set_states;
static fmi2GetContinuousStatesTYPE *get_states;
static fmi2GetDerivativesTYPE *get_derivatives;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env; (void)category;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d] ", name, (int)status);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static fmi2CallbackFunctions callbacks = { logger, calloc, free, NULL, NULL };
static const char *guid;
static fmi2ValueReference in_vr[3], out_vr[64];
static size_t n_out, nx;
static int nset;
static char **sets;

static fmi2Component start(fmi2Type type) {
    fmi2Component c = instantiate("bench", type, guid, "", &callbacks, fmi2False, fmi2False);
    if (!c || setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK || enter(c) != fmi2OK) { fprintf(stderr, "start failed\n"); exit(3); }
    for (int i = 0; i < nset; i++) {
        char kind = sets[i][0];
        fmi2ValueReference vr = (fmi2ValueReference)strtoul(sets[i] + 2, NULL, 10);
        const char *eq = strchr(sets[i], '=');
        fmi2Status st;
        if (!eq) { fprintf(stderr, "bad SET %s\n", sets[i]); exit(2); }
        if (kind == 'r') { double v = strtod(eq + 1, NULL); st = set_real(c, &vr, 1, &v); }
        else if (kind == 'i') { fmi2Integer v = atoi(eq + 1); st = set_integer(c, &vr, 1, &v); }
        else { fmi2Boolean v = atoi(eq + 1); st = set_boolean(c, &vr, 1, &v); }
        if (st != fmi2OK) { fprintf(stderr, "set %s failed\n", sets[i]); exit(3); }
    }
    if (exit_init(c) != fmi2OK) { fprintf(stderr, "exit init failed\n"); exit(3); }
    if (type == fmi2ModelExchange) {
        fmi2EventInfo e;
        if (new_discrete_states(c, &e) != fmi2OK || enter_ct(c) != fmi2OK) { fprintf(stderr, "ME start failed\n"); exit(3); }
    }
    return c;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static volatile double sink;

/* ns per time point of one run from a fresh instance; mode 0 cs, 1 me, 2 rhs. */
static double run(int mode, double speed, double h, long steps) {
    fmi2Component c = start(mode == 0 ? fmi2CoSimulation : fmi2ModelExchange);
    double out[64], x[8] = {0}, dx[8], acc = 0.0;
    if (mode == 2 && get_states(c, x, nx) != fmi2OK) exit(4);
    double t0 = now();
    for (long k = 0; k < steps; k++) {
        double t = k * h;
        double in[3] = { speed * t, speed, 0.0 };
        fmi2Status s;
        if (mode == 0) {
            s = set_real(c, in_vr, 3, in) | do_step(c, t, h, fmi2True) | get_real(c, out_vr, n_out, out);
        } else if (mode == 1) {
            s = set_time(c, t) | set_real(c, in_vr, 3, in) | get_real(c, out_vr, n_out, out);
        } else {
            s = set_time(c, t) | set_real(c, in_vr, 3, in) | set_states(c, x, nx) | get_derivatives(c, dx, nx)
                | get_real(c, out_vr, n_out, out);
            acc += dx[0];
        }
        if (s) { fprintf(stderr, "mode %d: time point %ld failed\n", mode, k); exit(4); }
        acc += out[n_out - 1];
    }
    double ns = (now() - t0) / (double)steps;
    sink = acc;
    free_instance(c);
    return ns;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 10) { fprintf(stderr, "usage: see me_eval.c\n"); return 2; }
    void *lib = fmu_load(argv[1]);
    if (!lib) { fprintf(stderr, "%s\n", fmu_load_error()); return 2; }
    instantiate = fmu_need(lib, "fmi2Instantiate");
    free_instance = fmu_need(lib, "fmi2FreeInstance");
    setup = fmu_need(lib, "fmi2SetupExperiment");
    enter = fmu_need(lib, "fmi2EnterInitializationMode");
    exit_init = fmu_need(lib, "fmi2ExitInitializationMode");
    set_real = fmu_need(lib, "fmi2SetReal");
    set_integer = fmu_need(lib, "fmi2SetInteger");
    set_boolean = fmu_need(lib, "fmi2SetBoolean");
    get_real = fmu_need(lib, "fmi2GetReal");
    do_step = fmu_need(lib, "fmi2DoStep");
    set_time = fmu_need(lib, "fmi2SetTime");
    new_discrete_states = fmu_need(lib, "fmi2NewDiscreteStates");
    enter_ct = fmu_need(lib, "fmi2EnterContinuousTimeMode");
    set_states = fmu_need(lib, "fmi2SetContinuousStates");
    get_states = fmu_need(lib, "fmi2GetContinuousStates");
    get_derivatives = fmu_need(lib, "fmi2GetDerivatives");
    guid = argv[2];
    if ((size_t)fmu_parse_vrs(argv[3], in_vr, 3) != 3) { fprintf(stderr, "need 3 inputs\n"); return 2; }
    n_out = (size_t)fmu_parse_vrs(argv[4], out_vr, 64);
    nx = strtoul(argv[5], NULL, 10);
    double speed = strtod(argv[6], NULL), h = strtod(argv[7], NULL);
    long steps = strtol(argv[8], NULL, 10);
    int rounds = atoi(argv[9]);
    nset = argc - 10;
    sets = argv + 10;
    if (rounds < 1 || rounds > 99 || nx > 8 || n_out < 1 || !(h > 0.0)) return 2;
    double r[3][99];
    const char *names[3] = { "cs", "me", "rhs" };
    const char *only = getenv("ME_EVAL_ONLY");
    int first = 0, last = 2;
    for (int m = 0; only && m < 3; m++)
        if (!strcmp(only, names[m])) first = last = m;
    for (int m = first; m <= last; m++) run(m, speed, h, steps / 10);  /* warm-up */
    for (int i = 0; i < rounds; i++)
        for (int m = first; m <= last; m++) r[m][i] = run(m, speed, h, steps);
    for (int m = first; m <= last; m++) {
        qsort(r[m], rounds, sizeof(double), cmp);
        printf("%s %.2f\n", names[m], r[m][rounds / 2]);
    }
    return 0;
}
