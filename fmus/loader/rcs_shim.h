/*
 * What the rubcosim FMU loader shim's files share (see rubcosim_fmu_loader.c): the FMI 2.0
 * types, the forwarded functions, the export library's function table and the helpers.
 * Nothing here is exported from the shim (it is built with -fvisibility=hidden).
 */
#ifndef RCS_SHIM_H
#define RCS_SHIM_H

#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <wchar.h>

#define RCS_EXPORT __attribute__((visibility("default")))

/* ------------------------------------------------------------------------------------------ */
/* FMI 2.0 types (declared here so no FMI headers are needed)                                 */
/* ------------------------------------------------------------------------------------------ */

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;

typedef enum {
    fmi2OK = 0,
    fmi2Warning = 1,
    fmi2Discard = 2,
    fmi2Error = 3,
    fmi2Fatal = 4,
    fmi2Pending = 5
} fmi2Status;

typedef enum { fmi2ModelExchange = 0, fmi2CoSimulation = 1 } fmi2Type;

typedef enum {
    fmi2DoStepStatus = 0,
    fmi2PendingStatus = 1,
    fmi2LastSuccessfulTime = 2,
    fmi2Terminated = 3
} fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String,
                                   fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

/* ------------------------------------------------------------------------------------------ */
/* Forwarded functions returning fmi2Status: X(name, parameter list, argument list)            */
/* ------------------------------------------------------------------------------------------ */

#define RCS_STATUS_FUNCTIONS(X)                                                                  \
    X(fmi2SetupExperiment,                                                                       \
      (fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime,    \
       fmi2Boolean stopTimeDefined, fmi2Real stopTime),                                          \
      (c, toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime))                    \
    X(fmi2EnterInitializationMode, (fmi2Component c), (c))                                       \
    X(fmi2ExitInitializationMode, (fmi2Component c), (c))                                        \
    X(fmi2Terminate, (fmi2Component c), (c))                                                     \
    X(fmi2Reset, (fmi2Component c), (c))                                                         \
    X(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))                      \
    X(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate state), (c, state))                        \
    X(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate * state), (c, state))                     \
    X(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate state, size_t * size),          \
      (c, state, size))                                                                          \
    X(fmi2SerializeFMUstate,                                                                     \
      (fmi2Component c, fmi2FMUstate state, fmi2Byte serializedState[], size_t size),           \
      (c, state, serializedState, size))                                                         \
    X(fmi2GetDirectionalDerivative,                                                              \
      (fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,                \
       const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],           \
       fmi2Real dvUnknown[]),                                                                    \
      (c, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown))                       \
    X(fmi2GetRealOutputDerivatives,                                                              \
      (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer order[],    \
       fmi2Real value[]),                                                                        \
      (c, vr, nvr, order, value))                                                                \
    X(fmi2DoStep,                                                                                \
      (fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,      \
       fmi2Boolean noSetFMUStatePriorToCurrentPoint),                                            \
      (c, currentCommunicationPoint, communicationStepSize, noSetFMUStatePriorToCurrentPoint))   \
    X(fmi2CancelStep, (fmi2Component c), (c))                                                    \
    X(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Status * value), (c, s, value)) \
    X(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Real * value),            \
      (c, s, value))                                                                             \
    X(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Integer * value),      \
      (c, s, value))                                                                             \
    X(fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind s, fmi2Boolean * value),      \
      (c, s, value))                                                                             \
    X(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind s, fmi2String * value),        \
      (c, s, value))


/* Forwarded with a check of their own (below the generic forwarders). */
#define RCS_CHECKED_STATUS_FUNCTIONS(X)                                                          \
    X(fmi2SetDebugLogging,                                                                       \
      (fmi2Component c, fmi2Boolean loggingOn, size_t nCategories, const fmi2String categories[]), \
      (c, loggingOn, nCategories, categories))                                                   \
    X(fmi2DeSerializeFMUstate,                                                                   \
      (fmi2Component c, const fmi2Byte serializedState[], size_t size, fmi2FMUstate * state),    \
      (c, serializedState, size, state))

/* The value accessors, with the FMI type of the variables they take: checked against the
 * model description (see check_types) before they are forwarded. */
#define RCS_VALUE_FUNCTIONS(X)                                                                   \
    X(fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]), (c, vr, nvr, value), 'R') \
    X(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]), (c, vr, nvr, value), 'I') \
    X(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]), (c, vr, nvr, value), 'B') \
    X(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]), (c, vr, nvr, value), 'S') \
    X(fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]), (c, vr, nvr, value), 'R') \
    X(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]), (c, vr, nvr, value), 'I') \
    X(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]), (c, vr, nvr, value), 'B') \
    X(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]), (c, vr, nvr, value), 'S')

typedef const char *(*fmi2GetTypesPlatform_t)(void);
typedef const char *(*fmi2GetVersion_t)(void);
typedef fmi2Component (*fmi2Instantiate_t)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                           const fmi2CallbackFunctions *, fmi2Boolean,
                                           fmi2Boolean);
typedef void (*fmi2FreeInstance_t)(fmi2Component);

#define RCS_TYPEDEF(name, params, args) typedef fmi2Status(*name##_t) params;
#define RCS_TYPEDEF_V(name, params, args, type) RCS_TYPEDEF(name, params, args)
RCS_STATUS_FUNCTIONS(RCS_TYPEDEF)
RCS_CHECKED_STATUS_FUNCTIONS(RCS_TYPEDEF)
RCS_VALUE_FUNCTIONS(RCS_TYPEDEF_V)
#undef RCS_TYPEDEF_V
#undef RCS_TYPEDEF

/* Function table of the export library; filled once, under g_lock, before the first instance. */
typedef struct {
    fmi2GetTypesPlatform_t fmi2GetTypesPlatform;
    fmi2GetVersion_t fmi2GetVersion;
    fmi2Instantiate_t fmi2Instantiate;
    fmi2FreeInstance_t fmi2FreeInstance;
#define RCS_MEMBER(name, params, args) name##_t name;
#define RCS_MEMBER_V(name, params, args, type) name##_t name;
    RCS_STATUS_FUNCTIONS(RCS_MEMBER)
    RCS_CHECKED_STATUS_FUNCTIONS(RCS_MEMBER)
    RCS_VALUE_FUNCTIONS(RCS_MEMBER_V)
#undef RCS_MEMBER_V
#undef RCS_MEMBER
} rcs_api;

#define RCS_MSG_SIZE 12288

typedef struct {
    char text[RCS_MSG_SIZE];
    size_t len;
} msgbuf;

typedef struct {
    int found;
    char file[PATH_MAX];
    char executable[PATH_MAX];
    char libpython[PATH_MAX];
    char soname[256];
    char version[32];
} runtime_record;

typedef int (*py_is_initialized_t)(void);
typedef const char *(*py_get_version_t)(void);
typedef wchar_t *(*py_decode_locale_t)(const char *, size_t *);
typedef void (*py_set_program_name_t)(const wchar_t *);
typedef void (*py_initialize_ex_t)(int);
typedef void *(*py_eval_save_thread_t)(void);

typedef struct {
    py_is_initialized_t is_initialized;
    py_get_version_t get_version;
    py_decode_locale_t decode_locale;
    py_set_program_name_t set_program_name;
    py_initialize_ex_t initialize_ex;
    py_eval_save_thread_t save_thread;
} py_api;

typedef struct {
    fmi2CallbackFunctions callbacks; /* what pythonfmu gets; its componentEnvironment is this */
    const fmi2CallbackFunctions *host;
    int logging_on; /* the host's */
} rcs_env;

extern rcs_api g_api;
extern pthread_mutex_t g_lock;
extern int g_ready;              /* export library loaded and table filled */
extern void (*g_finalize)(void); /* pythonfmu's finalizePythonInterpreter, if exported */
extern char g_self_path[PATH_MAX];               /* absolute path of this shim */
extern char g_python_desc[2 * PATH_MAX + 64];    /* which Python is used, for messages */
extern __thread int t_error_logged; /* an error was logged during the call in progress */

/* rcs_util.c */
void msg_add(msgbuf *m, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void log_message(const fmi2CallbackFunctions *functions, fmi2String instanceName,
                        fmi2Status status, const char *category, const char *message);
const char *label_sep(const char *label);
int copy_str(char *dst, size_t size, const char *src);
int is_executable_file(const char *path);
int is_elf_file(const char *path);
void dirname_inplace(char *path);
int major_minor(const char *version, char *out, size_t size);
int uri_to_path(const char *uri, char *out, size_t size);

/* rcs_python_find.c */
void trim(char *s);
void read_runtime_record(const char *resources, runtime_record *rec);
const char *resolve_py_api(void *handle, py_api *api);
int try_libpython(const char *label, const char *candidate, py_api *api, msgbuf *tried,
                         char *loaded, size_t loaded_size);
int executable_version(const char *exe, char *out, size_t size);
int accept_executable(const char *label, const char *exe, const char *lib_version,
                             int require_elf, msgbuf *tried);
int find_on_path(const char *name, const char *lib_version, char *out, size_t size,
                        msgbuf *tried);
int find_sibling_executable(const char *lib_path, const char *lib_version, char *out,
                                   size_t size, msgbuf *tried);
void append_hint(msgbuf *m, const runtime_record *rec);
int missing_modules(char *out, size_t size);

/* rcs_python.c */
int ensure_python(const char *resources, msgbuf *err, msgbuf *info, int *warn);
int load_export_library(const char *resources, msgbuf *err);

/* rcs_instances.c */
rcs_env *routed_callbacks(const fmi2CallbackFunctions *host, fmi2Boolean loggingOn);
fmi2Status answer(fmi2Status status);
void remember_instance(fmi2Component c, const fmi2CallbackFunctions *functions,
                              fmi2String name, rcs_env *env);
rcs_env *forget_instance(fmi2Component c);
void log_refusal(fmi2Component c, const char *text);
int set_host_logging(fmi2Component c, fmi2Boolean on);

#endif
