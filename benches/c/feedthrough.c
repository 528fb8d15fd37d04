/* The baseline of scripts/bench_ratio.py: an FMI 2.0 co-simulation FMU that computes nothing,
 * equivalent in the work of each call to the Modelica Reference FMUs' "Feedthrough" built the
 * same way (-O3): a state-mask check per call, NULL checks, a dirty flag that makes fmi2GetReal
 * "calculate" the outputs once after inputs change, a switch over value references per value,
 * and a fixed-step loop in fmi2DoStep that advances time and checks for events and termination.
 * It has 3 Real inputs (vr 0..2) and 8 Real outputs (vr 3..10), each output a copy of an input,
 * so the host loop (set 3 inputs, step, get 8 outputs) has the shape of the FMU under test.
 * As in the Reference FMUs, where the model's accessors (model.c), the co-simulation loop
 * (cosimulation.c) and the FMI functions are separate translation units, the per-value accessors,
 * the calculation and the step loop are out-of-line calls (noinline), and each value's status is
 * folded into the call's. Only the functions the benchmark host calls are implemented. Written
 * for this project. */
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

enum { Instantiated = 1, InitializationMode = 2, StepComplete = 4, Terminated = 8 };
#define FIXED_SOLVER_STEP 1e-3
#define N_IN 3
#define N_OUT 8

typedef struct {
    int state;
    double time;
    double in[N_IN];
    double out[N_OUT];
    int dirty;
    int terminate;
    int next_event_defined;
    double next_event;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char name[64];
} Instance;

static int allowed(Instance *c, int mask, const char *f) {
    if (!c) return 0;
    if (!(c->state & mask)) {
        if (c->logger) c->logger(c->env, c->name, fmi2Error, "logStatusError", "%s: illegal call sequence", f);
        return 0;
    }
    return 1;
}

#define NOINLINE __attribute__((noinline))
/* Folds a call's status into the function's, evaluating the call once. */
#define FOLD(status, call) do { fmi2Status s_ = (call); if (s_ > (status)) (status) = s_; } while (0)

static NOINLINE fmi2Status calculate(Instance *c) {
    for (int i = 0; i < N_OUT; i++) c->out[i] = c->in[i % N_IN];
    return fmi2OK;
}

static NOINLINE fmi2Status get_float64(Instance *c, fmi2ValueReference vr, double *values, size_t n, size_t *index) {
    if (*index >= n) return fmi2Error;
    switch (vr) {
    case 0: case 1: case 2: values[(*index)++] = c->in[vr]; return fmi2OK;
    case 3: case 4: case 5: case 6: case 7: case 8: case 9: case 10: values[(*index)++] = c->out[vr - 3]; return fmi2OK;
    default: return fmi2Error;
    }
}

static NOINLINE fmi2Status set_float64(Instance *c, fmi2ValueReference vr, const double *values, size_t n, size_t *index) {
    if (*index >= n) return fmi2Error;
    switch (vr) {
    case 0: case 1: case 2: c->in[vr] = values[(*index)++]; return fmi2OK;
    default: return fmi2Error;
    }
}

static NOINLINE fmi2Status do_step(Instance *s, double t_next) {
    double eps = (1.0 + (s->time < 0 ? -s->time : s->time)) * 2.220446049250313e-16;
    while (s->time + FIXED_SOLVER_STEP < t_next + eps) {
        s->time += FIXED_SOLVER_STEP;
        if (s->next_event_defined && s->time >= s->next_event) s->dirty = 1;
        if (s->terminate) return fmi2Discard;
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *f, fmi2Boolean visible, fmi2Boolean logging) {
    (void)guid; (void)res; (void)visible; (void)logging;
    if (type != fmi2CoSimulation || !f) return NULL;
    Instance *c = calloc(1, sizeof(Instance));
    if (!c) return NULL;
    c->state = Instantiated;
    c->logger = f->logger;
    c->env = f->componentEnvironment;
    strncpy(c->name, name ? name : "", sizeof c->name - 1);
    c->dirty = 1;
    return c;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    Instance *s = c;
    if (!allowed(s, Instantiated, "fmi2SetupExperiment")) return fmi2Error;
    s->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!allowed(s, Instantiated, "fmi2EnterInitializationMode")) return fmi2Error;
    s->state = InitializationMode;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *s = c;
    if (!allowed(s, InitializationMode, "fmi2ExitInitializationMode")) return fmi2Error;
    if (s->dirty) { calculate(s); s->dirty = 0; }
    s->state = StepComplete;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *s = c;
    if (!allowed(s, Instantiated | InitializationMode | StepComplete, "fmi2SetReal")) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fmi2Error;
    fmi2Status status = fmi2OK;
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        FOLD(status, set_float64(s, vr[i], value, nvr, &index));
        if (status > fmi2Warning) return status;
    }
    s->dirty = 1;
    return status;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *s = c;
    if (!allowed(s, InitializationMode | StepComplete | Terminated, "fmi2GetReal")) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fmi2Error;
    fmi2Status status = fmi2OK;
    if (s->dirty) {
        FOLD(status, calculate(s));
        if (status > fmi2Warning) return status;
        s->dirty = 0;
    }
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        FOLD(status, get_float64(s, vr[i], value, nvr, &index));
        if (status > fmi2Warning) return status;
    }
    return status;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    (void)t; (void)noSetPrior;
    Instance *s = c;
    if (!allowed(s, StepComplete, "fmi2DoStep")) return fmi2Error;
    if (h <= 0) return fmi2Error;
    return do_step(s, t + h);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *s = c;
    if (!allowed(s, StepComplete, "fmi2Terminate")) return fmi2Error;
    s->state = Terminated;
    return fmi2OK;
}
