/*
 * rubcosim FMU loader shim.
 *
 * pythonfmu ships one binary, libpythonfmu-export.so, as binaries/linux64/<id>.so.  That library
 * does not link libpython: its Py* symbols are undefined and must already be present in the
 * process.  When it has to start Python itself it uses the program name "./PythonFMU", so the
 * interpreter finds neither the user's virtual environment nor its site-packages, and it calls
 * Py_Finalize when the library is unloaded, which is known to crash at exit once numpy has been
 * imported.  Plain C hosts (FMI tools with no Python inside) therefore cannot run such FMUs.
 *
 * This shim becomes binaries/linux64/<id>.so; the pythonfmu library is stored next to it as
 * <id>_pythonfmu_export.so.  On the first fmi2Instantiate it makes sure a Python interpreter is
 * running in the process (loading libpython RTLD_GLOBAL and initialising it with the program name
 * of a real Python executable, so sys.prefix, pyvenv.cfg and site-packages resolve exactly as for
 * that executable), then loads the export library and forwards every FMI 2.0 call to it.
 *
 * Design rules:
 *  - If Python is already initialised in the process (e.g. an FMU loaded by fmpy) nothing is
 *    started; pythonfmu then uses the host's interpreter as before.
 *  - Python is never finalised and neither libpython nor the export library is ever unloaded
 *    (RTLD_NODELETE), so process exit does not run interpreter teardown.
 *  - Only symbols with stable signatures are resolved with dlsym (Py_IsInitialized, Py_GetVersion,
 *    Py_DecodeLocale, Py_SetProgramName, Py_InitializeEx, PyEval_SaveThread), so no Python
 *    headers are needed to build the shim.
 *  - Every failure is reported through the FMI logger and fmi2Instantiate returns NULL.
 *
 * Environment variables understood: RUBCOSIM_LIBPYTHON (path of the shared libpython to load)
 * and RUBCOSIM_PYTHON (Python executable whose environment should be used).
 * The runtime recorded at build time is read from <resources>/rubcosim_python.txt (key=value lines:
 * executable, libpython, soname, version).
 *
 * The files: this one holds the exported FMI 2.0 functions (the forwarding, the type checks, the
 * input derivatives); rcs_instances.c the live instances and how a call is refused;
 * rcs_python.c starting Python and loading the export library; rcs_python_find.c finding
 * libpython and a matching executable; rcs_util.c small helpers; rcs_shim.h what they share.
 */
#include "rcs_shim.h"

/* ------------------------------------------------------------------------------------------ */
/* Exported FMI 2.0 API                                                                       */
/* ------------------------------------------------------------------------------------------ */

RCS_EXPORT const char *fmi2GetTypesPlatform(void)
{
    return g_api.fmi2GetTypesPlatform ? g_api.fmi2GetTypesPlatform() : "default";
}

RCS_EXPORT const char *fmi2GetVersion(void)
{
    return g_api.fmi2GetVersion ? g_api.fmi2GetVersion() : "2.0";
}

/* ------------------------------------------------------------------------------------------ */
/* Input derivatives                                                                          */
/* ------------------------------------------------------------------------------------------ */

/* pythonfmu has no fmi2SetRealInputDerivatives.  The slave declares, for each real input, two
 * tunable parameters that carry its first and second time derivative; the build lists them in
 * <resources>/rubcosim_input_derivatives.txt, one "input_vr order carrier_vr" per line, and this
 * shim turns the call into fmi2SetReal on the carriers.  Filled once, under g_lock. */
#define RCS_MAX_DERIVATIVES 1024
static struct {
    fmi2ValueReference input;
    fmi2Integer order;
    fmi2ValueReference carrier;
} g_der[RCS_MAX_DERIVATIVES];
static size_t g_n_der = 0;

static void read_derivative_table(const char *resources)
{
    g_n_der = 0;
    if (resources == NULL) return;
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/rubcosim_input_derivatives.txt", resources) >=
        (int)sizeof path)
        return;
    FILE *f = fopen(path, "r");
    if (f == NULL) return;
    unsigned long input, carrier;
    long order;
    while (g_n_der < RCS_MAX_DERIVATIVES && fscanf(f, "%lu %ld %lu", &input, &order, &carrier) == 3) {
        g_der[g_n_der].input = (fmi2ValueReference)input;
        g_der[g_n_der].order = (fmi2Integer)order;
        g_der[g_n_der].carrier = (fmi2ValueReference)carrier;
        g_n_der++;
    }
    fclose(f);
}

RCS_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                                  size_t nvr, const fmi2Integer order[],
                                                  const fmi2Real value[])
{
    if (g_api.fmi2SetReal == NULL) return fmi2Error;
    /* one fmi2SetReal for every carrier, in chunks of RCS_DER_BATCH: each call into the
     * Python slave costs microseconds whatever the number of values it carries */
    enum { RCS_DER_BATCH = 64 };
    fmi2ValueReference carriers[RCS_DER_BATCH];
    fmi2Real values[RCS_DER_BATCH];
    size_t n = 0;
    t_error_logged = 0;
    for (size_t i = 0; i < nvr; i++) {
        size_t k = 0;
        while (k < g_n_der && !(g_der[k].input == vr[i] && g_der[k].order == order[i])) k++;
        if (k == g_n_der) return fmi2Error; /* not a real input, or an order above 2 */
        carriers[n] = g_der[k].carrier;
        values[n] = value[i];
        if (++n == RCS_DER_BATCH || i + 1 == nvr) {
            fmi2Status status = answer(g_api.fmi2SetReal(c, carriers, n, values));
            if (status > fmi2Warning) return status;
            n = 0;
        }
    }
    return fmi2OK;
}


/* ------------------------------------------------------------------------------------------ */
/* Variable types: a wrongly typed call is refused here with fmi2Error                         */
/* ------------------------------------------------------------------------------------------ */

/* pythonfmu turns every Python exception into fmi2Fatal and drops the instance's Python
 * object, so a host that calls fmi2SetReal on an Integer variable (a caller's mistake, which
 * FMI 2.0 answers with fmi2Error) lost every instance of the model.  The build lists each
 * variable in <resources>/rubcosim_variables.txt, one "vr type name" per line (type R, I, B or
 * S), and the value accessors check their references against it before forwarding: a wrong
 * type or an unknown reference gets fmi2Error with a logged message, and the instance stays
 * usable.  Filled once, under g_lock; an FMU without the file is not checked. */
#define RCS_MAX_VR 65536
static char *g_vtype;       /* type letter by value reference, 0 where none */
static char **g_vname;      /* name by value reference */
static size_t g_n_vtype;    /* entries in both */

static void read_variable_table(const char *resources)
{
    if (resources == NULL || g_vtype != NULL) return;
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/rubcosim_variables.txt", resources) >= (int)sizeof path)
        return;
    FILE *f = fopen(path, "r");
    if (f == NULL) return;
    char *type = calloc(RCS_MAX_VR, 1);
    char **name = calloc(RCS_MAX_VR, sizeof(char *));
    size_t n = 0;
    unsigned long vr;
    char letter, text[256];
    while (type != NULL && name != NULL && fscanf(f, "%lu %c %255s", &vr, &letter, text) == 3) {
        if (vr >= RCS_MAX_VR) continue;
        type[vr] = letter;
        free(name[vr]);
        name[vr] = strdup(text);
        if (vr + 1 > n) n = vr + 1;
    }
    fclose(f);
    if (type == NULL || name == NULL) {
        free(type);
        free(name);
        return;
    }
    g_vname = name;
    g_n_vtype = n;
    g_vtype = type;
}

static const char *type_name(char letter)
{
    switch (letter) {
    case 'R': return "Real";
    case 'I': return "Integer";
    case 'B': return "Boolean";
    case 'S': return "String";
    default: return "unknown";
    }
}

/* fmi2OK when every reference names a variable of type `want`; else the refusal, logged. */
static fmi2Status check_types(fmi2Component c, const char *function, const fmi2ValueReference vr[],
                              size_t nvr, char want)
{
    if (g_vtype == NULL) return fmi2OK;
    for (size_t i = 0; i < nvr; i++) {
        char have = vr[i] < g_n_vtype ? g_vtype[vr[i]] : 0;
        if (have == want) continue;
        char text[512];
        if (have == 0)
            snprintf(text, sizeof text, "%s: no variable has value reference %lu; call refused",
                     function, (unsigned long)vr[i]);
        else
            snprintf(text, sizeof text,
                     "%s: variable %s (value reference %lu) is of type %s, not %s; call refused, "
                     "nothing set or read (use fmi2%s%s)",
                     function, g_vname[vr[i]] ? g_vname[vr[i]] : "?", (unsigned long)vr[i],
                     type_name(have), type_name(want), strncmp(function, "fmi2Set", 7) ? "Get" : "Set",
                     type_name(have));
        log_refusal(c, text);
        return fmi2Error;
    }
    return fmi2OK;
}

RCS_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                         fmi2String fmuGUID, fmi2String fmuResourceLocation,
                                         const fmi2CallbackFunctions *functions,
                                         fmi2Boolean visible, fmi2Boolean loggingOn)
{
    pthread_mutex_lock(&g_lock);
    if (!g_ready) {
        static msgbuf err, info; /* large; guarded by g_lock */
        err.len = info.len = 0;
        err.text[0] = info.text[0] = '\0';
        int warn = 0;
        char resources_buf[PATH_MAX];
        const char *resources = NULL;
        if (uri_to_path(fmuResourceLocation, resources_buf, sizeof resources_buf) == 0)
            resources = resources_buf;
        int ok = ensure_python(resources, &err, &info, &warn) == 0 &&
                 load_export_library(resources, &err) == 0;
        if (ok) {
            read_derivative_table(resources);
            read_variable_table(resources);
            g_ready = 1;
            if (info.len > 0 && (warn || loggingOn))
                log_message(functions, instanceName, warn ? fmi2Warning : fmi2OK,
                            warn ? "logStatusWarning" : "logAll", info.text);
        } else {
            log_message(functions, instanceName, fmi2Error, "logStatusError", err.text);
        }
    }
    int ready = g_ready;
    pthread_mutex_unlock(&g_lock);
    if (!ready) return NULL;
    rcs_env *env = routed_callbacks(functions, loggingOn);
    int routed = env != NULL && env->host != NULL;
    fmi2Component c = g_api.fmi2Instantiate(instanceName, fmuType, fmuGUID, fmuResourceLocation,
                                            routed ? &env->callbacks : functions, visible,
                                            routed ? 1 : loggingOn);
    if (c != NULL)
        remember_instance(c, functions, instanceName, env);
    else
        free(env);
    if (c == NULL) {
        /* Routed through the shim's logger, pythonfmu runs with logging on and its
           errors reach the host whatever loggingOn says; unrouted (no host logger to
           route to), it reports its Python exceptions only when logging is on. */
        char text[sizeof g_python_desc + 512];
        snprintf(text, sizeof text,
                 "rubcosim FMU loader: pythonfmu's fmi2Instantiate failed (Python: %s).%s If a "
                 "module is missing, set RUBCOSIM_PYTHON to the python of the environment that "
                 "has the FMU's dependencies.",
                 g_python_desc,
                 routed || loggingOn
                     ? ""
                     : " Its error details are only logged with loggingOn=fmi2True.");
        log_message(functions, instanceName, fmi2Error, "logStatusError", text);
    }
    return c;
}

RCS_EXPORT void fmi2FreeInstance(fmi2Component c)
{
    rcs_env *env = c != NULL ? forget_instance(c) : NULL;
    if (c != NULL && g_api.fmi2FreeInstance != NULL) g_api.fmi2FreeInstance(c);
    free(env);
}

#define RCS_FORWARD(name, params, args)                                                          \
    RCS_EXPORT fmi2Status name params                                                            \
    {                                                                                            \
        if (g_api.name == NULL) return fmi2Error;                                                \
        t_error_logged = 0;                                                                      \
        return answer(g_api.name args);                                                          \
    }
RCS_STATUS_FUNCTIONS(RCS_FORWARD)
#undef RCS_FORWARD

/* The host's logging choice is kept by the shim (see rcs_logger); pythonfmu keeps logging. */
RCS_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                                          size_t nCategories, const fmi2String categories[])
{
    int found = set_host_logging(c, loggingOn);
    if (found || g_api.fmi2SetDebugLogging == NULL) return found ? fmi2OK : fmi2Error;
    return g_api.fmi2SetDebugLogging(c, loggingOn, nCategories, categories);
}

/* The slave reads bytes that are not a state of this FMU (garbage, truncated, another
 * FMU's) as a mark that serialises to nothing: refused here, and the mark freed. */
RCS_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                              size_t size, fmi2FMUstate *state)
{
    if (g_api.fmi2DeSerializeFMUstate == NULL || g_api.fmi2SerializedFMUstateSize == NULL ||
        g_api.fmi2FreeFMUstate == NULL)
        return fmi2Error;
    t_error_logged = 0;
    fmi2Status status = answer(g_api.fmi2DeSerializeFMUstate(c, serializedState, size, state));
    if (status > fmi2Warning) return status;
    size_t back = 0;
    if (g_api.fmi2SerializedFMUstateSize(c, *state, &back) == fmi2OK && back > 0) return status;
    g_api.fmi2FreeFMUstate(c, state);
    *state = NULL;
    char text[256];
    snprintf(text, sizeof text,
             "fmi2DeSerializeFMUstate: these %lu bytes are not a serialised state of this FMU; "
             "call refused",
             (unsigned long)size);
    log_refusal(c, text);
    return fmi2Error;
}

#define RCS_FORWARD_CHECKED(name, params, args, type)                                            \
    RCS_EXPORT fmi2Status name params                                                            \
    {                                                                                            \
        if (g_api.name == NULL) return fmi2Error;                                                \
        if (check_types(c, #name, vr, nvr, type) != fmi2OK) return fmi2Error;                    \
        t_error_logged = 0;                                                                      \
        return answer(g_api.name args);                                                          \
    }
RCS_VALUE_FUNCTIONS(RCS_FORWARD_CHECKED)
#undef RCS_FORWARD_CHECKED
