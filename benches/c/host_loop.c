/* Native host loop of scripts/bench_ratio.py: loads two FMI 2.0 co-simulation FMUs' shared objects
 * with dlopen, as an importer does, and times the same loop on both, alternating runs so that both
 * see the same machine state:
 *   loop:   per step fmi2SetReal of 3 inputs, fmi2DoStep (h = 1 ms), fmi2GetReal of N outputs
 *   dostep: fmi2DoStep alone
 * It prints the median ns per step of each and their ratio. Written for this project.
 * Environment: HOST_H = the communication step h [s] (default 1e-3); HOST_INSTANCES = the number
 * of instances of each FMU (default 1), stepped in turn at every communication point, as one host
 * steps many machines; the figures are then per instance and step.
 *
 * usage: host_loop BASE.so BASE_GUID BASE_IN BASE_OUT  FMU.so FMU_GUID FMU_IN FMU_OUT  SPEED STEPS ROUNDS [SET...]
 *   *_IN, *_OUT: comma-separated value references (3 inputs; the outputs read each step)
 *   SET: r:VR=VALUE, i:VR=VALUE or b:VR=VALUE, set on the FMU (not the base) in initialization mode
 *   The FMU's inputs are (crank angle, speed, acceleration) = (SPEED*t, SPEED, 0). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "fmi2Functions.h"
#include "../../tests/c/fmu_load.h"

typedef struct {
    void *lib;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2GetRealTYPE *get_real;
    fmi2DoStepTYPE *do_step;
    const char *guid;
    fmi2ValueReference in[3];
    fmi2ValueReference out[64];
    size_t n_out;
} Fmu;

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

static void load(Fmu *f, const char *path, const char *guid, const char *in, const char *out) {
    f->lib = fmu_load(path);
    if (!f->lib) { fprintf(stderr, "%s\n", fmu_load_error()); exit(2); }
    f->instantiate = fmu_need(f->lib, "fmi2Instantiate");
    f->free_instance = fmu_need(f->lib, "fmi2FreeInstance");
    f->setup = fmu_need(f->lib, "fmi2SetupExperiment");
    f->enter = fmu_need(f->lib, "fmi2EnterInitializationMode");
    f->exit_init = fmu_need(f->lib, "fmi2ExitInitializationMode");
    f->set_real = fmu_need(f->lib, "fmi2SetReal");
    f->set_integer = fmu_sym(f->lib, "fmi2SetInteger");
    f->set_boolean = fmu_sym(f->lib, "fmi2SetBoolean");
    f->get_real = fmu_need(f->lib, "fmi2GetReal");
    f->do_step = fmu_need(f->lib, "fmi2DoStep");
    f->guid = guid;
    if ((size_t)fmu_parse_vrs(in, f->in, 3) != 3) { fprintf(stderr, "need 3 inputs\n"); exit(2); }
    f->n_out = (size_t)fmu_parse_vrs(out, f->out, 64);
}

static fmi2CallbackFunctions callbacks = { logger, calloc, free, NULL, NULL };

static fmi2Component start(Fmu *f, int nset, char **set) {
    fmi2Component c = f->instantiate("bench", fmi2CoSimulation, f->guid, "", &callbacks, fmi2False, fmi2False);
    if (!c || f->setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK || f->enter(c) != fmi2OK) { fprintf(stderr, "start failed\n"); exit(3); }
    for (int i = 0; i < nset; i++) {
        char kind = set[i][0];
        fmi2ValueReference vr = (fmi2ValueReference)strtoul(set[i] + 2, NULL, 10);
        const char *eq = strchr(set[i], '=');
        fmi2Status st;
        if (!eq) { fprintf(stderr, "bad SET %s\n", set[i]); exit(2); }
        if (kind == 'r') { double v = strtod(eq + 1, NULL); st = f->set_real(c, &vr, 1, &v); }
        else if (kind == 'i') { fmi2Integer v = atoi(eq + 1); st = f->set_integer(c, &vr, 1, &v); }
        else { fmi2Boolean v = atoi(eq + 1); st = f->set_boolean(c, &vr, 1, &v); }
        if (st != fmi2OK) { fprintf(stderr, "set %s failed\n", set[i]); exit(3); }
    }
    if (f->exit_init(c) != fmi2OK) { fprintf(stderr, "exit init failed\n"); exit(3); }
    return c;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static volatile double sink;

static double h = 1e-3;
static long instances = 1;

/* ns per instance and step of one run from fresh instances. */
static double run(Fmu *f, int nset, char **set, double speed, long steps, int dostep_only) {
    fmi2Component *cs = malloc(instances * sizeof *cs);
    if (!cs) exit(2);
    for (long i = 0; i < instances; i++) cs[i] = start(f, nset, set);
    double out[64], acc = 0.0;
    double t0 = now();
    for (long k = 0; k < steps; k++) {
        double t = k * h;
        for (long i = 0; i < instances; i++) {
            fmi2Component c = cs[i];
            if (!dostep_only) {
                double in[3] = { speed * t, speed, 0.0 };
                fmi2Status s1 = f->set_real(c, f->in, 3, in);
                fmi2Status s2 = f->do_step(c, t, h, fmi2True);
                fmi2Status s3 = f->get_real(c, f->out, f->n_out, out);
                if (s1 | s2 | s3) { fprintf(stderr, "step %ld failed (set %d, step %d, get %d)\n", k, (int)s1, (int)s2, (int)s3); exit(4); }
                acc += out[f->n_out - 1];
            } else if (f->do_step(c, t, h, fmi2True) != fmi2OK) {
                fprintf(stderr, "step %ld failed\n", k); exit(4);
            }
        }
    }
    double ns = (now() - t0) / ((double)steps * instances);
    sink = acc;
    for (long i = 0; i < instances; i++) f->free_instance(cs[i]);
    free(cs);
    return ns;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 12) { fprintf(stderr, "usage: see host_loop.c\n"); return 2; }
    Fmu base, fmu;
    load(&base, argv[1], argv[2], argv[3], argv[4]);
    load(&fmu, argv[5], argv[6], argv[7], argv[8]);
    double speed = strtod(argv[9], NULL);
    long steps = strtol(argv[10], NULL, 10);
    int rounds = atoi(argv[11]);
    int nset = argc - 12;
    char **set = argv + 12;
    if (rounds < 1 || rounds > 99) return 2;
    if (getenv("HOST_H")) h = strtod(getenv("HOST_H"), NULL);
    if (getenv("HOST_INSTANCES")) instances = strtol(getenv("HOST_INSTANCES"), NULL, 10);
    if (!(h > 0.0) || instances < 1) { fprintf(stderr, "bad HOST_H or HOST_INSTANCES\n"); return 2; }
    for (int mode = 0; mode < 2; mode++) {
        double b[99], f[99];
        run(&base, 0, NULL, speed, steps / 10, mode);  /* warm-up */
        run(&fmu, nset, set, speed, steps / 10, mode);
        for (int r = 0; r < rounds; r++) {
            b[r] = run(&base, 0, NULL, speed, steps, mode);
            f[r] = run(&fmu, nset, set, speed, steps, mode);
        }
        qsort(b, rounds, sizeof(double), cmp);
        qsort(f, rounds, sizeof(double), cmp);
        printf("%s base %.2f fmu %.2f ratio %.3f\n", mode ? "dostep" : "loop", b[rounds / 2], f[rounds / 2],
               f[rounds / 2] / b[rounds / 2]);
    }
    return 0;
}
