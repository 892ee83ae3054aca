/*
 * fmu.c -- FMI 2.0 Co-Simulation wrapper of a symcushion touchdown step.
 *
 * Written by hand; symcushion.compiled.fmu.build_fmu compiles it with the generated
 * touchdown_step.c (the scene's step Function, CasADi C) and fmu_model.h (the
 * scene's sizes, start values and value-reference tables), against the FMI 2.0
 * headers of the importer (FMPy's at build time). docs/toolchain.md, "Using
 * symcushion from Simulink / Modelica", describes the FMU.
 *
 * fmi2DoStep advances touchdown_step(x, p, dt) at the scene's dt, n = h/dt
 * steps per communication interval h (an error unless n is whole within
 * FMU_STEP_RTOL). The inputs, an external force F and torque tau on the body
 * (world frame), are held over the interval and applied around each step as
 * kicks of the body's velocity, half before and half after (velocity
 * Verlet's split):
 *     v <- v + (dt/2) F/m,  omega <- omega + (dt/2) I^-1 R^T tau,
 * R the attitude before the step for the first kick and after it for the
 * second; the acceleration output gains F/m. symcushion.compiled.fmu.held_input_step is
 * the same in Python, operation for operation. With zero inputs the kicks add
 * zero: the FMU is the step.
 *
 * The FMU state (fmi2GetFMUstate, serialisation) is the struct State: x, y,
 * p, u, time and the number of steps taken, all doubles.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "touchdown_step.h"
#include "fmu_model.h"

/* the order of the FMI calls, for their checks */
typedef enum {
    PHASE_INSTANTIATED, PHASE_INITIALIZATION, PHASE_STEPPING, PHASE_TERMINATED, PHASE_ERROR
} Phase;

/* everything a saved FMU state holds */
typedef struct {
    double x[FMU_NX];   /* state of touchdown_step */
    double y[FMU_NY];   /* outputs of the last step (fmu_y0 before the first) */
    double p[FMU_NP];   /* parameters */
    double u[FMU_NU];   /* inputs: force (N), torque (N m), world frame */
    double time;        /* s */
    double steps;       /* touchdown steps taken since the start */
    double energy[FMU_NE]; /* per leg, J since the start: axial, bending, friction */
} State;

/* a serialised state: this tag, the FMU's GUID, then the State's bytes */
static const char STATE_TAG[8] = {'s', 'y', 'm', 'c', 'f', 'm', 'u', '1'};
#define SERIAL_SIZE (sizeof(STATE_TAG) + sizeof(FMU_GUID) + sizeof(State))

typedef struct {
    State s;
    Phase phase;
    fmi2Boolean logging;
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocate;
    fmi2CallbackFreeMemory free_memory;
    fmi2ComponentEnvironment environment;
    char *name;
    double x_next[FMU_NX];
    const casadi_real *arg[touchdown_step_SZ_ARG];
    casadi_real *res[touchdown_step_SZ_RES];
    casadi_int iw[touchdown_step_SZ_IW + 1];
    casadi_real w[touchdown_step_SZ_W + 1];
    int mem;
} Instance;

/* ------------------------------------------------------------------------- */
/* logging                                                                   */
/* ------------------------------------------------------------------------- */
static void log_message(const Instance *m, fmi2Status status, const char *format, ...)
{
    char text[1024];
    va_list ap;
    size_t i;
    if (m == NULL || m->logger == NULL || (status == fmi2OK && !m->logging)) return;
    va_start(ap, format);
    vsnprintf(text, sizeof text, format, ap);
    va_end(ap);
    /* the logger reads its message as a printf format */
    for (i = 0; text[i] != '\0'; i++) {
        if (text[i] == '%') text[i] = ' ';
    }
    m->logger(m->environment, m->name, status,
              status == fmi2OK ? "logAll" : "logStatusError", text);
}

static fmi2Status fail(Instance *m, const char *function, const char *why)
{
    log_message(m, fmi2Error, "%s: %s", function, why);
    return fmi2Error;
}

/* ------------------------------------------------------------------------- */
/* the step with held inputs                                                 */
/* ------------------------------------------------------------------------- */
static void reset_state(State *s)
{
    memcpy(s->x, fmu_x0, sizeof s->x);
    memcpy(s->y, fmu_y0, sizeof s->y);
    memcpy(s->p, fmu_p0, sizeof s->p);
    memset(s->u, 0, sizeof s->u);
    s->time = 0.0;
    s->steps = 0.0;
    memset(s->energy, 0, sizeof s->energy);
}

/* I^-1 b for the inertia (xx, yy, zz, xy, xz, yz) by its adjugate; det returned */
static double inverse_inertia_times(const double *I, const double *b, double *out)
{
    const double a = I[0], bb = I[1], c = I[2], d = I[3], e = I[4], f = I[5];
    const double adj[3][3] = {
        {bb * c - f * f, e * f - d * c, d * f - e * bb},
        {e * f - d * c, a * c - e * e, d * e - a * f},
        {d * f - e * bb, d * e - a * f, a * bb - d * d}};
    const double det = a * adj[0][0] + d * adj[0][1] + e * adj[0][2];
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = (adj[i][0] * b[0] + adj[i][1] * b[1] + adj[i][2] * b[2]) / det;
    }
    return det;
}

/* the held force and torque over half_dt: v and omega of the state x */
static void external_kick(double *x, const double *p, const double *u, double half_dt)
{
    const double m = p[FMU_P_MASS];
    const double *q = x + FMU_X_ATTITUDE;
    const double w = q[0], qx = q[1], qy = q[2], qz = q[3];
    /* R, body to world, as symcushion.scheme.quaternion.quat_to_rot_np (not renormalised) */
    const double R[3][3] = {
        {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - w * qz), 2 * (qx * qz + w * qy)},
        {2 * (qx * qy + w * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - w * qx)},
        {2 * (qx * qz - w * qy), 2 * (qy * qz + w * qx), 1 - 2 * (qx * qx + qy * qy)}};
    double torque_body[3], alpha[3];
    int i;
    for (i = 0; i < 3; i++) {
        x[FMU_X_VELOCITY + i] = x[FMU_X_VELOCITY + i] + half_dt * (u[i] / m);
        torque_body[i] = R[0][i] * u[3] + R[1][i] * u[4] + R[2][i] * u[5];
    }
    inverse_inertia_times(p + FMU_P_INERTIA, torque_body, alpha);
    for (i = 0; i < 3; i++) {
        x[FMU_X_OMEGA + i] = x[FMU_X_OMEGA + i] + half_dt * alpha[i];
    }
}

/* acceleration output before the first step: the initial state's feet are free */
static void initial_acceleration(State *s)
{
    int i;
    for (i = 0; i < 3; i++) {
        s->y[FMU_Y_ACCELERATION + i] = s->p[FMU_P_GRAVITY + i] + s->u[i] / s->p[FMU_P_MASS];
    }
}

static int all_finite(const double *v, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) return 0;
    }
    return 1;
}

/* one touchdown step with the held inputs; 0 on success */
static int step(Instance *m)
{
    const double dt = FMU_DT, half_dt = 0.5 * FMU_DT;
    State *s = &m->s;
    int i;
    external_kick(s->x, s->p, s->u, half_dt);
    m->arg[0] = s->x;
    m->arg[1] = s->p;
    m->arg[2] = &dt;
    m->res[0] = m->x_next;
    m->res[1] = s->y;
    if (touchdown_step(m->arg, m->res, m->iw, m->w, m->mem)) return 1;
    external_kick(m->x_next, s->p, s->u, half_dt);
    for (i = 0; i < 3; i++) {
        s->y[FMU_Y_ACCELERATION + i] = s->y[FMU_Y_ACCELERATION + i] + s->u[i] / s->p[FMU_P_MASS];
    }
    if (!all_finite(m->x_next, FMU_NX)) return 2;
    memcpy(s->x, m->x_next, sizeof s->x);
    for (i = 0; i < FMU_NE; i++) {
        s->energy[i] = s->energy[i] + s->y[fmu_energy_index[i]];
    }
    s->steps += 1.0;
    return 0;
}

/* the body parameters the kicks divide by: a clear error instead of a NaN state */
static const char *bad_body(const double *p)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    double scratch[3];
    const double *I = p + FMU_P_INERTIA;
    if (!(p[FMU_P_MASS] > 0.0) || !isfinite(p[FMU_P_MASS]))
        return "`mass` must be positive and finite; set a positive mass (kg)";
    if (!(I[0] > 0.0 && I[1] > 0.0 && I[2] > 0.0)
        || !(inverse_inertia_times(I, zero, scratch) > 0.0))
        return "`inertia.*` must be a positive definite tensor (kg m^2); check inertia.xx, "
               "yy, zz and the products xy, xz, yz";
    return NULL;
}

/* ------------------------------------------------------------------------- */
/* instance                                                                  */
/* ------------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    Instance probe, *m;
    size_t n;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL || functions->freeMemory == NULL)
        return NULL;
    memset(&probe, 0, sizeof probe);
    probe.logger = functions->logger;
    probe.environment = functions->componentEnvironment;
    probe.name = (char *)(instanceName ? instanceName : "?");
    if (fmuType != fmi2CoSimulation) {
        fail(&probe, "fmi2Instantiate", "this FMU is Co-Simulation only; instantiate it as "
             "fmi2CoSimulation");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, FMU_GUID) != 0) {
        fail(&probe, "fmi2Instantiate", "the GUID does not match this FMU's "
             "modelDescription.xml (" FMU_GUID "); re-import the FMU");
        return NULL;
    }
    m = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (m == NULL) return NULL;
    m->logger = functions->logger;
    m->allocate = functions->allocateMemory;
    m->free_memory = functions->freeMemory;
    m->environment = functions->componentEnvironment;
    m->logging = loggingOn;
    n = strlen(probe.name) + 1;
    m->name = (char *)m->allocate(n, 1);
    if (m->name == NULL) {
        m->free_memory(m);
        return NULL;
    }
    memcpy(m->name, probe.name, n);
    reset_state(&m->s);
    touchdown_step_incref();
    m->mem = touchdown_step_checkout();
    m->phase = PHASE_INSTANTIATED;
    log_message(m, fmi2OK, "instantiated the FMU of scene " FMU_SCENE);
    return m;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return;
    touchdown_step_release(m->mem);
    touchdown_step_decref();
    m->free_memory(m->name);
    m->free_memory(m);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Instance *m = (Instance *)c;
    (void)nCategories;
    (void)categories;
    if (m == NULL) return fmi2Error;
    m->logging = loggingOn;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *m = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (m == NULL) return fmi2Error;
    if (m->phase != PHASE_INSTANTIATED)
        return fail(m, "fmi2SetupExperiment", "call it after fmi2Instantiate or fmi2Reset");
    m->s.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    if (m->phase != PHASE_INSTANTIATED)
        return fail(m, "fmi2EnterInitializationMode", "call it once, after fmi2Instantiate");
    m->phase = PHASE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    if (m->phase != PHASE_INITIALIZATION)
        return fail(m, "fmi2ExitInitializationMode", "call fmi2EnterInitializationMode first");
    initial_acceleration(&m->s);
    m->phase = PHASE_STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    m->phase = PHASE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    reset_state(&m->s);
    m->phase = PHASE_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------------------- */
/* variables                                                                 */
/* ------------------------------------------------------------------------- */
static double *real_slot(Instance *m, fmi2ValueReference vr)
{
    const int i = fmu_real_index[vr];
    switch (fmu_real_kind[vr]) {
    case FMU_KIND_PARAMETER: return &m->s.p[i];
    case FMU_KIND_INPUT: return &m->s.u[i];
    case FMU_KIND_STATE: return &m->s.x[i];
    case FMU_KIND_ENERGY: return &m->s.energy[i];
    default: return &m->s.y[i];
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    Instance *m = (Instance *)c;
    size_t k;
    if (m == NULL) return fmi2Error;
    if (m->s.steps == 0.0) initial_acceleration(&m->s);
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= FMU_N_REAL) {
            log_message(m, fmi2Error, "fmi2GetReal: no Real variable has value reference %u; "
                        "see modelDescription.xml", (unsigned)vr[k]);
            return fmi2Error;
        }
        value[k] = *real_slot(m, vr[k]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    Instance *m = (Instance *)c;
    size_t k;
    if (m == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= FMU_N_REAL) {
            log_message(m, fmi2Error, "fmi2SetReal: no Real variable has value reference %u; "
                        "see modelDescription.xml", (unsigned)vr[k]);
            return fmi2Error;
        }
        if (fmu_real_kind[vr[k]] != FMU_KIND_PARAMETER && fmu_real_kind[vr[k]] != FMU_KIND_INPUT) {
            log_message(m, fmi2Error, "fmi2SetReal: `%s` is an output; only the parameters and "
                        "the inputs can be set", fmu_real_name[vr[k]]);
            return fmi2Error;
        }
        if (!isfinite(value[k])) {
            log_message(m, fmi2Error, "fmi2SetReal: `%s` must be finite, got %g",
                        fmu_real_name[vr[k]], value[k]);
            return fmi2Error;
        }
        *real_slot(m, vr[k]) = value[k];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    Instance *m = (Instance *)c;
    size_t k;
    if (m == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= FMU_N_INTEGER) {
            log_message(m, fmi2Error, "fmi2GetInteger: no Integer variable has value reference "
                        "%u; see modelDescription.xml", (unsigned)vr[k]);
            return fmi2Error;
        }
        value[k] = (fmi2Integer)m->s.y[fmu_integer_index[vr[k]]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    (void)vr;
    (void)value;
    if (nvr == 0) return fmi2OK;
    return fail((Instance *)c, "fmi2SetInteger", "the Integer variables (contact modes) are "
                "outputs and cannot be set");
}

/* Boolean and String variables: the FMU has none; an empty call is fine */
#define NO_VARIABLES(function, value_type, type_name)                                   \
    fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,     \
                        value_type value[])                                             \
    {                                                                                   \
        (void)vr;                                                                       \
        (void)value;                                                                    \
        if (nvr == 0) return fmi2OK;                                                    \
        return fail((Instance *)c, #function, "this FMU has no " type_name " variables"); \
    }
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean, "Boolean")
NO_VARIABLES(fmi2SetBoolean, const fmi2Boolean, "Boolean")
NO_VARIABLES(fmi2GetString, fmi2String, "String")
NO_VARIABLES(fmi2SetString, const fmi2String, "String")

/* ------------------------------------------------------------------------- */
/* FMU state                                                                 */
/* ------------------------------------------------------------------------- */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *m = (Instance *)c;
    if (m == NULL || FMUstate == NULL) return fmi2Error;
    if (*FMUstate == NULL) {
        *FMUstate = m->allocate(1, sizeof(State));
        if (*FMUstate == NULL) return fail(m, "fmi2GetFMUstate", "out of memory");
    }
    memcpy(*FMUstate, &m->s, sizeof(State));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    if (FMUstate == NULL)
        return fail(m, "fmi2SetFMUstate", "the state is NULL; pass one from fmi2GetFMUstate");
    memcpy(&m->s, FMUstate, sizeof(State));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *m = (Instance *)c;
    if (m == NULL || FMUstate == NULL) return fmi2Error;
    if (*FMUstate != NULL) m->free_memory(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    if (c == NULL || size == NULL) return fmi2Error;
    *size = SERIAL_SIZE;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    Instance *m = (Instance *)c;
    if (m == NULL) return fmi2Error;
    if (FMUstate == NULL || size < SERIAL_SIZE)
        return fail(m, "fmi2SerializeFMUstate", "needs a state and a buffer of "
                    "fmi2SerializedFMUstateSize bytes");
    memcpy(serializedState, STATE_TAG, sizeof STATE_TAG);
    memcpy(serializedState + sizeof STATE_TAG, FMU_GUID, sizeof FMU_GUID);
    memcpy(serializedState + sizeof STATE_TAG + sizeof FMU_GUID, FMUstate, sizeof(State));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *m = (Instance *)c;
    if (m == NULL || FMUstate == NULL) return fmi2Error;
    if (size != SERIAL_SIZE || memcmp(serializedState, STATE_TAG, sizeof STATE_TAG) != 0
        || memcmp(serializedState + sizeof STATE_TAG, FMU_GUID, sizeof FMU_GUID) != 0)
        return fail(m, "fmi2DeSerializeFMUstate", "these bytes are not a state serialised by "
                    "this FMU (another FMU, scene or build); serialise a state of this FMU");
    if (*FMUstate == NULL) {
        *FMUstate = m->allocate(1, sizeof(State));
        if (*FMUstate == NULL) return fail(m, "fmi2DeSerializeFMUstate", "out of memory");
    }
    memcpy(*FMUstate, serializedState + sizeof STATE_TAG + sizeof FMU_GUID, sizeof(State));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return fail((Instance *)c, "fmi2GetDirectionalDerivative", "not provided (derivatives of "
                "the step come from symcushion's CasADi model in Python)");
}

/* ------------------------------------------------------------------------- */
/* co-simulation                                                             */
/* ------------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2SetRealInputDerivatives", "the inputs are held over a "
                "communication step (canInterpolateInputs is false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2GetRealOutputDerivatives", "not provided "
                "(maxOutputDerivativeOrder is 0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *m = (Instance *)c;
    const double h = communicationStepSize;
    const double n = floor(h / FMU_DT + 0.5);
    const char *bad;
    double k;
    int code;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (m == NULL) return fmi2Error;
    if (m->phase != PHASE_STEPPING)
        return fail(m, "fmi2DoStep", "call fmi2ExitInitializationMode first (or the FMU "
                    "stopped on an error: fmi2Reset it)");
    if (!(h > 0.0) || n < 1.0 || fabs(h - n * FMU_DT) > FMU_STEP_RTOL * h) {
        log_message(m, fmi2Error, "fmi2DoStep: the communication step %.17g s is not a whole "
                    "number of the scene's steps dt = %.17g s (h/dt = %.17g); use a multiple "
                    "of dt, or rebuild the FMU from a scene with another dt",
                    h, (double)FMU_DT, h / FMU_DT);
        return fmi2Error;
    }
    if ((bad = bad_body(m->s.p)) != NULL) return fail(m, "fmi2DoStep", bad);
    for (k = 0.0; k < n; k += 1.0) {
        code = step(m);
        if (code != 0) {
            m->phase = PHASE_ERROR;
            log_message(m, fmi2Error, "fmi2DoStep: %s at t = %.17g s (step %.0f of the "
                        "interval from %.17g s); the FMU stops here", code == 1
                        ? "touchdown_step failed" : "the state became non-finite (NaN or inf)",
                        currentCommunicationPoint + k * FMU_DT, k + 1.0,
                        currentCommunicationPoint);
            return fmi2Error;
        }
    }
    m->s.time = currentCommunicationPoint + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    return fail((Instance *)c, "fmi2CancelStep", "fmi2DoStep never runs asynchronously");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *m = (Instance *)c;
    if (m == NULL || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = m->s.time;
    return fmi2OK;
}

/* fmi2DoStep never returns fmi2Pending: no asynchronous status to ask for */
#define NO_STATUS(function, value_type)                                                 \
    fmi2Status function(fmi2Component c, const fmi2StatusKind s, value_type *value)    \
    {                                                                                   \
        (void)c;                                                                        \
        (void)s;                                                                        \
        (void)value;                                                                    \
        return fmi2Discard;                                                             \
    }
NO_STATUS(fmi2GetStatus, fmi2Status)
NO_STATUS(fmi2GetIntegerStatus, fmi2Integer)
NO_STATUS(fmi2GetBooleanStatus, fmi2Boolean)
NO_STATUS(fmi2GetStringStatus, fmi2String)
