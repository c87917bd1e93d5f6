/* A bouncing ball as a plain FMI 2.0 co-simulation FMU, written against the standard headers
 * only (no rubcosim, no pythonfmu): what "an FMU from another tool" looks like to rubcosim.
 *
 * h'' = -g; when h reaches 0 moving down, v -> -e v; below v_min the ball rests on the floor.
 * Between bounces the motion is a parabola, so each fmi2DoStep advances exactly, locating every
 * bounce inside the step (its own internal events).  State: h, v, time, bounce count; it can be
 * got, set and serialised, so a master can roll it back.
 *
 * Value references: 0 h [m] (output), 1 v [m/s] (output), 2 bounces (Integer output),
 * 3 g [m/s2], 4 e [1], 5 h0 [m], 6 v0 [m/s] (fixed parameters), 7 phase (String output:
 * "rising", "falling" or "resting"), 8 resting (Boolean output): outputs of the other FMI
 * types, as tools export them; 9 crash_at_step (Integer parameter, 0 = never): the FMU
 * segfaults in its n-th fmi2DoStep call, standing in for a defective FMU.
 */
#include <signal.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

typedef struct {
    double h, v, t, g, e, h0, v0;
    int bounces;
} state_t;

typedef struct {
    state_t s;
    fmi2CallbackFunctions cb;
    char name[128];
    int crash_at_step, steps; /* not part of the FMU state: every fmi2DoStep call counts */
} ball_t;

static const double V_MIN = 1e-6; /* m/s: slower rebounds come to rest */

static void log_error(ball_t *b, const char *msg)
{
    if (b->cb.logger) b->cb.logger(b->cb.componentEnvironment, b->name, fmi2Error, "logStatusError", msg);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[])
{
    (void)c; (void)on; (void)n; (void)cat;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean vis, fmi2Boolean log)
{
    (void)guid; (void)res; (void)vis; (void)log;
    if (type != fmi2CoSimulation) return NULL;
    ball_t *b = calloc(1, sizeof *b);
    if (!b) return NULL;
    if (cb) b->cb = *cb;
    strncpy(b->name, name ? name : "ball", sizeof b->name - 1);
    b->s.g = 9.81; b->s.e = 0.7; b->s.h0 = 1.0; b->s.v0 = 0.0;
    return b;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stopDef, fmi2Real stop)
{
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    ((ball_t *)c)->s.t = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    ball_t *b = c;
    if (!(b->s.g > 0.0) || !(b->s.e >= 0.0 && b->s.e <= 1.0) || !(b->s.h0 >= 0.0)) {
        log_error(b, "bouncing ball: need g > 0, 0 <= e <= 1 and h0 >= 0");
        return fmi2Error;
    }
    b->s.h = b->s.h0;
    b->s.v = b->s.v0;
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c)
{
    ball_t *b = c;
    double g = b->s.g, e = b->s.e, h0 = b->s.h0, v0 = b->s.v0;
    memset(&b->s, 0, sizeof b->s);
    b->s.g = g; b->s.e = e; b->s.h0 = h0; b->s.v0 = v0;
    return fmi2OK;
}

static double *real_slot(ball_t *b, fmi2ValueReference vr)
{
    switch (vr) {
    case 0: return &b->s.h;
    case 1: return &b->s.v;
    case 3: return &b->s.g;
    case 4: return &b->s.e;
    case 5: return &b->s.h0;
    case 6: return &b->s.v0;
    default: return NULL;
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[])
{
    for (size_t i = 0; i < n; i++) {
        double *p = real_slot(c, vr[i]);
        if (!p) return fmi2Error;
        v[i] = *p;
    }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[])
{
    for (size_t i = 0; i < n; i++) {
        if (vr[i] < 3) return fmi2Error; /* outputs cannot be set */
        double *p = real_slot(c, vr[i]);
        if (!p) return fmi2Error;
        *p = v[i];
    }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == 2) v[i] = ((ball_t *)c)->s.bounces;
        else if (vr[i] == 9) v[i] = ((ball_t *)c)->crash_at_step;
        else return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 9) return fmi2Error;
        ((ball_t *)c)->crash_at_step = v[i];
    }
    return fmi2OK;
}
static int resting(const state_t *s) { return s->h <= 0.0 && s->v == 0.0; }

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 8) return fmi2Error;
        v[i] = resting(&((ball_t *)c)->s) ? fmi2True : fmi2False;
    }
    return fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{
    (void)c; (void)vr; (void)v;
    return n ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{
    const state_t *s = &((ball_t *)c)->s;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != 7) return fmi2Error;
        v[i] = resting(s) ? "resting" : (s->v > 0.0 ? "rising" : "falling");
    }
    return fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{
    (void)c; (void)vr; (void)v;
    return n ? fmi2Error : fmi2OK;
}

/* --- state ------------------------------------------------------------------------------- */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    if (*state == NULL) *state = malloc(sizeof(state_t));
    if (*state == NULL) return fmi2Error;
    memcpy(*state, &((ball_t *)c)->s, sizeof(state_t));
    return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    memcpy(&((ball_t *)c)->s, state, sizeof(state_t));
    return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c; (void)state;
    *size = sizeof(state_t);
    return fmi2OK;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte out[], size_t size)
{
    (void)c;
    if (size < sizeof(state_t)) return fmi2Error;
    memcpy(out, state, sizeof(state_t));
    return fmi2OK;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *state)
{
    (void)c;
    if (size != sizeof(state_t)) return fmi2Error;
    if (*state == NULL) *state = malloc(sizeof(state_t));
    if (*state == NULL) return fmi2Error;
    memcpy(*state, in, sizeof(state_t));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference k[], size_t nk, const fmi2Real dk[],
                                        fmi2Real du[])
{
    (void)c; (void)u; (void)nu; (void)k; (void)nk; (void)dk; (void)du;
    return fmi2Error;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[])
{
    (void)c; (void)vr; (void)n; (void)o; (void)v;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[])
{
    (void)c; (void)vr; (void)n; (void)o; (void)v;
    return fmi2Error;
}

/* --- stepping: exact parabolas between bounces ------------------------------------------ */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noPrior)
{
    (void)noPrior;
    ball_t *b = c;
    if (b->crash_at_step > 0 && ++b->steps == b->crash_at_step) raise(SIGSEGV);
    state_t *s = &b->s;
    if (!(h >= 0.0)) {
        log_error(b, "bouncing ball: negative step");
        return fmi2Error;
    }
    double left = h;
    for (int guard = 0; left > 0.0 && guard < 100000; guard++) {
        if (s->h <= 0.0 && fabs(s->v) < V_MIN) { /* at rest */
            s->h = 0.0;
            s->v = 0.0;
            break;
        }
        /* time to the floor: h + v tau - g tau^2 / 2 = 0, the positive root */
        double tau = (s->v + sqrt(s->v * s->v + 2.0 * s->g * fmax(s->h, 0.0))) / s->g;
        if (tau > left) {
            s->h += s->v * left - 0.5 * s->g * left * left;
            s->v -= s->g * left;
            left = 0.0;
        } else {
            s->v = -s->e * (s->v - s->g * tau);
            s->h = 0.0;
            s->bounces++;
            left -= tau;
            if (s->v < V_MIN) s->v = 0.0;
        }
    }
    s->t = t + h;
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v)
{
    (void)c; (void)k; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v)
{
    if (k != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ((ball_t *)c)->s.t;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v)
{
    (void)c; (void)k; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v)
{
    (void)c; (void)k; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v)
{
    (void)c; (void)k; (void)v;
    return fmi2Discard;
}
