/* Live instances of the shim and how it refuses calls. */
#include "rcs_shim.h"

/* ------------------------------------------------------------------------------------------ */
/* Refusals: an error the slave logged makes the call's answer fmi2Error                        */
/* ------------------------------------------------------------------------------------------ */

/* pythonfmu answers a Python exception with fmi2Fatal and drops references it does not own
 * (a later call may crash the process), and it has no other way for the slave to refuse a
 * call.  So the slave (fmi_slave.py) never raises: it refuses a call by logging the reason
 * at fmi2Error and returning normally.  pythonfmu is given the host's callbacks with the
 * logger routed through rcs_logger, which notes on the calling thread that an error was
 * logged; the forwarders below answer such a call with fmi2Error where pythonfmu answered
 * fmi2OK or fmi2Warning.  (A failed step stays fmi2Discard.)  pythonfmu passes each
 * message as the format argument with no arguments: it is forwarded as text.
 * pythonfmu logs nothing at all when logging is off, so it always runs with logging on;
 * the host's choice (fmi2Instantiate's loggingOn, fmi2SetDebugLogging) is applied here:
 * with logging off, only warnings and errors reach the host's logger. */

__thread int t_error_logged;

static void rcs_logger(fmi2ComponentEnvironment env, fmi2String instanceName, fmi2Status status,
                       fmi2String category, fmi2String message, ...)
{
    if (status >= fmi2Error && status != fmi2Pending) t_error_logged = 1;
    const rcs_env *e = env;
    if (e != NULL && !e->logging_on && status < fmi2Warning) return;
    if (e != NULL && e->host != NULL && e->host->logger != NULL)
        log_message(e->host, instanceName, status, category ? category : "",
                    message ? message : "");
}

rcs_env *routed_callbacks(const fmi2CallbackFunctions *host, fmi2Boolean loggingOn)
{
    rcs_env *e = calloc(1, sizeof *e);
    if (e == NULL || host == NULL) return e;
    e->logging_on = loggingOn;
    fmi2CallbackFunctions routed = {rcs_logger, host->allocateMemory, host->freeMemory,
                                    host->stepFinished, e};
    memcpy(&e->callbacks, &routed, sizeof routed);
    e->host = host;
    return e;
}

/* The answer to a forwarded call, which started with t_error_logged = 0. */
fmi2Status answer(fmi2Status status)
{
    return t_error_logged && status <= fmi2Warning ? fmi2Error : status;
}

/* The host's logger, instance name and routed callbacks of each live instance. */
#define RCS_MAX_INSTANCES 1024
static struct {
    fmi2Component c;
    const fmi2CallbackFunctions *functions;
    char *name;
    rcs_env *env;
} g_inst[RCS_MAX_INSTANCES];

void remember_instance(fmi2Component c, const fmi2CallbackFunctions *functions,
                              fmi2String name, rcs_env *env)
{
    pthread_mutex_lock(&g_lock);
    for (size_t i = 0; i < RCS_MAX_INSTANCES; i++) {
        if (g_inst[i].c == NULL) {
            g_inst[i].c = c;
            g_inst[i].functions = functions;
            g_inst[i].name = strdup(name ? name : "");
            g_inst[i].env = env;
            env = NULL;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    /* more live instances than slots: the routed callbacks leak rather than dangle */
    (void)env;
}

/* Forget an instance; returns its routed callbacks, to free once pythonfmu has let go. */
rcs_env *forget_instance(fmi2Component c)
{
    rcs_env *env = NULL;
    pthread_mutex_lock(&g_lock);
    for (size_t i = 0; i < RCS_MAX_INSTANCES; i++) {
        if (g_inst[i].c == c) {
            free(g_inst[i].name);
            env = g_inst[i].env;
            g_inst[i].c = NULL;
            g_inst[i].name = NULL;
            g_inst[i].env = NULL;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    return env;
}

/* Log `text` at fmi2Error through the host's logger of instance c. */
void log_refusal(fmi2Component c, const char *text)
{
    const fmi2CallbackFunctions *functions = NULL;
    char name[256] = "";
    pthread_mutex_lock(&g_lock);
    for (size_t k = 0; k < RCS_MAX_INSTANCES; k++) {
        if (g_inst[k].c == c) {
            functions = g_inst[k].functions;
            snprintf(name, sizeof name, "%s", g_inst[k].name ? g_inst[k].name : "");
            break;
        }
    }
    pthread_mutex_unlock(&g_lock); /* the host's logger runs outside the lock */
    log_message(functions, name, fmi2Error, "logStatusError", text);
}

/* The host's logging choice for instance c (fmi2SetDebugLogging); 0 if c is not known. */
int set_host_logging(fmi2Component c, fmi2Boolean on)
{
    int found = 0;
    pthread_mutex_lock(&g_lock);
    for (size_t k = 0; k < RCS_MAX_INSTANCES; k++) {
        if (g_inst[k].c == c && g_inst[k].env != NULL) {
            g_inst[k].env->logging_on = on;
            found = 1;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    return found;
}
