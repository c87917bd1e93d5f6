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
 */
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
static struct {
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
} g_api;

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static int g_ready = 0;            /* export library loaded and table filled */
static void (*g_finalize)(void);   /* pythonfmu's finalizePythonInterpreter, if exported */
static char g_self_path[PATH_MAX]; /* absolute path of this shim, found at load time */
static char g_python_desc[2 * PATH_MAX + 64]; /* which Python is used, for error messages */

/* ------------------------------------------------------------------------------------------ */
/* Small helpers                                                                              */
/* ------------------------------------------------------------------------------------------ */

#define RCS_MSG_SIZE 12288

typedef struct {
    char text[RCS_MSG_SIZE];
    size_t len;
} msgbuf;

static void msg_add(msgbuf *m, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void msg_add(msgbuf *m, const char *fmt, ...)
{
    if (m->len >= sizeof(m->text) - 1) return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(m->text + m->len, sizeof(m->text) - m->len, fmt, ap);
    va_end(ap);
    if (n < 0) return;
    m->len += (size_t)n;
    if (m->len >= sizeof(m->text)) m->len = sizeof(m->text) - 1;
}

/* Send a message through the host's logger (or stderr if it gave none).  '%' is doubled because
 * the message is passed as the printf-style format argument of the logger. */
static void log_message(const fmi2CallbackFunctions *functions, fmi2String instanceName,
                        fmi2Status status, const char *category, const char *message)
{
    size_t n = strlen(message);
    char *escaped = malloc(2 * n + 1);
    if (escaped == NULL) return;
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        escaped[j++] = message[i];
        if (message[i] == '%') escaped[j++] = '%';
    }
    escaped[j] = '\0';
    if (functions != NULL && functions->logger != NULL) {
        functions->logger(functions->componentEnvironment, instanceName ? instanceName : "",
                          status, category, escaped);
    } else {
        fprintf(stderr, "[%s] %s\n", category, message);
    }
    free(escaped);
}

/* "RUBCOSIM_X=" labels are glued to the value, other labels get a space. */
static const char *label_sep(const char *label)
{
    size_t n = strlen(label);
    return (n > 0 && label[n - 1] == '=') ? "" : " ";
}

static int copy_str(char *dst, size_t size, const char *src)
{
    size_t n = strlen(src);
    if (n >= size) return -1;
    memcpy(dst, src, n + 1);
    return 0;
}

static int is_executable_file(const char *path)
{
    struct stat st;
    return path != NULL && path[0] != '\0' && stat(path, &st) == 0 && S_ISREG(st.st_mode) &&
           access(path, X_OK) == 0;
}

/* PATH may hold wrapper scripts (pyenv shims, conda wrappers); as program name these would
 * mislead CPython's prefix search, so the PATH fallback only accepts real ELF binaries. */
static int is_elf_file(const char *path)
{
    unsigned char magic[4];
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return 0;
    ssize_t n = read(fd, magic, sizeof magic);
    close(fd);
    return n == 4 && magic[0] == 0x7f && magic[1] == 'E' && magic[2] == 'L' && magic[3] == 'F';
}

static void dirname_inplace(char *path)
{
    char *slash = strrchr(path, '/');
    if (slash == NULL) {
        strcpy(path, ".");
    } else if (slash == path) {
        path[1] = '\0';
    } else {
        *slash = '\0';
    }
}

/* Extract "X.Y" from a version string such as "3.11.7 (main, ...)"; returns 0 on success. */
static int major_minor(const char *version, char *out, size_t size)
{
    if (version == NULL) return -1;
    const char *p = version;
    while (*p == ' ' || *p == '\t') p++;
    const char *start = p;
    int dots = 0;
    while ((*p >= '0' && *p <= '9') || *p == '.') {
        if (*p == '.' && ++dots == 2) break;
        p++;
    }
    if (dots < 1 || p == start || (size_t)(p - start) >= size || p[-1] == '.') return -1;
    memcpy(out, start, (size_t)(p - start));
    out[p - start] = '\0';
    return 0;
}

/* Convert the fmuResourceLocation URI into a file system path ("file:///a%20b" -> "/a b"). */
static int uri_to_path(const char *uri, char *out, size_t size)
{
    if (uri == NULL || uri[0] == '\0') return -1;
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
        if (*p != '/') p = strchr(p, '/'); /* file://host/path: keep the path part */
        if (p == NULL) return -1;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
    size_t j = 0;
    for (; *p != '\0'; p++) {
        char c = *p;
        if (c == '%' && p[1] != '\0' && p[2] != '\0') {
            char hex[3] = {p[1], p[2], '\0'};
            char *end = NULL;
            long v = strtol(hex, &end, 16);
            if (end == hex + 2) {
                c = (char)v;
                p += 2;
            }
        }
        if (j + 1 >= size) return -1;
        out[j++] = c;
    }
    while (j > 1 && out[j - 1] == '/') j--;
    out[j] = '\0';
    return j > 0 ? 0 : -1;
}

/* ------------------------------------------------------------------------------------------ */
/* Runtime record (<resources>/rubcosim_python.txt)                                           */
/* ------------------------------------------------------------------------------------------ */

typedef struct {
    int found;
    char file[PATH_MAX];
    char executable[PATH_MAX];
    char libpython[PATH_MAX];
    char soname[256];
    char version[32];
} runtime_record;

static void trim(char *s)
{
    size_t n = strlen(s);
    while (n > 0 && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ' || s[n - 1] == '\t'))
        s[--n] = '\0';
    size_t k = 0;
    while (s[k] == ' ' || s[k] == '\t') k++;
    if (k > 0) memmove(s, s + k, n - k + 1);
}

static void read_runtime_record(const char *resources, runtime_record *rec)
{
    memset(rec, 0, sizeof *rec);
    if (resources == NULL) return;
    if (snprintf(rec->file, sizeof rec->file, "%s/rubcosim_python.txt", resources) >=
        (int)sizeof rec->file)
        return;
    FILE *f = fopen(rec->file, "r");
    if (f == NULL) return;
    rec->found = 1;
    char line[PATH_MAX + 64];
    while (fgets(line, sizeof line, f) != NULL) {
        trim(line);
        if (line[0] == '#' || line[0] == '\0') continue;
        char *eq = strchr(line, '=');
        if (eq == NULL) continue;
        *eq = '\0';
        char *key = line;
        char *value = eq + 1;
        trim(key);
        trim(value);
        if (strcmp(key, "executable") == 0) {
            copy_str(rec->executable, sizeof rec->executable, value);
        } else if (strcmp(key, "libpython") == 0) {
            copy_str(rec->libpython, sizeof rec->libpython, value);
        } else if (strcmp(key, "soname") == 0) {
            copy_str(rec->soname, sizeof rec->soname, value);
        } else if (strcmp(key, "version") == 0) {
            copy_str(rec->version, sizeof rec->version, value);
        }
    }
    fclose(f);
}

/* ------------------------------------------------------------------------------------------ */
/* Python start-up                                                                            */
/* ------------------------------------------------------------------------------------------ */

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

/* Resolve the start-up functions from `handle` (RTLD_DEFAULT or a libpython handle).  Returns
 * the name of the first missing symbol, or NULL when all were found. */
static const char *resolve_py_api(void *handle, py_api *api)
{
    memset(api, 0, sizeof *api);
    if ((api->is_initialized = (py_is_initialized_t)dlsym(handle, "Py_IsInitialized")) == NULL)
        return "Py_IsInitialized";
    if ((api->get_version = (py_get_version_t)dlsym(handle, "Py_GetVersion")) == NULL)
        return "Py_GetVersion";
    if ((api->decode_locale = (py_decode_locale_t)dlsym(handle, "Py_DecodeLocale")) == NULL)
        return "Py_DecodeLocale";
    if ((api->set_program_name = (py_set_program_name_t)dlsym(handle, "Py_SetProgramName")) ==
        NULL)
        return "Py_SetProgramName";
    if ((api->initialize_ex = (py_initialize_ex_t)dlsym(handle, "Py_InitializeEx")) == NULL)
        return "Py_InitializeEx";
    if ((api->save_thread = (py_eval_save_thread_t)dlsym(handle, "PyEval_SaveThread")) == NULL)
        return "PyEval_SaveThread";
    return NULL;
}

/* Try to load one libpython candidate.  It is first opened RTLD_LOCAL so that a file lacking the
 * needed symbols can be dropped again; an accepted one is promoted to RTLD_GLOBAL (numpy's
 * extension modules and the export library resolve Py* symbols from the global scope) and
 * RTLD_NODELETE (it must outlive everything, Python is never finalised). */
static int try_libpython(const char *label, const char *candidate, py_api *api, msgbuf *tried,
                         char *loaded, size_t loaded_size)
{
    if (candidate == NULL || candidate[0] == '\0') return 0;
    dlerror();
    void *local = dlopen(candidate, RTLD_NOW | RTLD_LOCAL);
    if (local == NULL) {
        const char *err = dlerror();
        msg_add(tried, "\n  - %s%s%s: %s", label, label_sep(label), candidate,
                err ? err : "dlopen failed");
        return 0;
    }
    const char *missing = resolve_py_api(local, api);
    if (missing != NULL) {
        msg_add(tried, "\n  - %s%s%s: loaded but has no symbol %s (not a usable libpython)",
                label, label_sep(label), candidate, missing);
        dlclose(local);
        return 0;
    }
    dlerror();
    void *global = dlopen(candidate, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE);
    if (global == NULL) {
        const char *err = dlerror();
        msg_add(tried, "\n  - %s%s%s: could not be made global: %s", label, label_sep(label),
                candidate, err ? err : "dlopen failed");
        dlclose(local);
        return 0;
    }
    dlclose(local); /* drop the extra reference; RTLD_NODELETE keeps the library mapped */
    resolve_py_api(global, api);
    copy_str(loaded, loaded_size, candidate);
    return 1;
}

/* Version ("X.Y") of a Python executable, without running it: from pyvenv.cfg of a virtual
 * environment, or from a file name such as python3.11 (after resolving symlinks). */
static int executable_version(const char *exe, char *out, size_t size)
{
    char dir[PATH_MAX];
    if (copy_str(dir, sizeof dir, exe) != 0) return -1;
    dirname_inplace(dir);
    for (int level = 0; level < 2; level++) {
        char cfg[PATH_MAX + 32];
        snprintf(cfg, sizeof cfg, "%s/pyvenv.cfg", dir);
        FILE *f = fopen(cfg, "r");
        if (f != NULL) {
            char line[1024];
            int ok = -1;
            while (ok != 0 && fgets(line, sizeof line, f) != NULL) {
                char *eq = strchr(line, '=');
                if (eq == NULL) continue;
                *eq = '\0';
                trim(line);
                if (strcmp(line, "version") == 0 || strcmp(line, "version_info") == 0)
                    ok = major_minor(eq + 1, out, size);
            }
            fclose(f);
            if (ok == 0) return 0;
        }
        dirname_inplace(dir);
    }
    char resolved[PATH_MAX];
    const char *names[2] = {exe, realpath(exe, resolved) ? resolved : NULL};
    for (int i = 0; i < 2; i++) {
        if (names[i] == NULL) continue;
        const char *base = strrchr(names[i], '/');
        base = base ? base + 1 : names[i];
        if (strncmp(base, "python", 6) == 0 && major_minor(base + 6, out, size) == 0 &&
            strchr(out, '.') != NULL)
            return 0;
    }
    return -1;
}

/* Accept an executable candidate if it exists and (when its version can be told) matches the
 * loaded libpython; a mismatch would silently use the wrong site-packages. */
static int accept_executable(const char *label, const char *exe, const char *lib_version,
                             int require_elf, msgbuf *tried)
{
    if (exe == NULL || exe[0] == '\0') return 0;
    if (!is_executable_file(exe)) {
        msg_add(tried, "\n  - %s%s%s: not an executable file", label, label_sep(label), exe);
        return 0;
    }
    if (require_elf && !is_elf_file(exe)) {
        msg_add(tried, "\n  - %s%s%s: not an ELF binary (wrapper script?), skipped", label,
                label_sep(label), exe);
        return 0;
    }
    char exe_version[32];
    if (lib_version[0] != '\0' && executable_version(exe, exe_version, sizeof exe_version) == 0 &&
        strcmp(exe_version, lib_version) != 0) {
        msg_add(tried, "\n  - %s%s%s: is Python %s but the loaded libpython is %s", label,
                label_sep(label), exe, exe_version, lib_version);
        return 0;
    }
    return 1;
}

static int find_on_path(const char *name, const char *lib_version, char *out, size_t size,
                        msgbuf *tried)
{
    const char *path = getenv("PATH");
    if (path == NULL || path[0] == '\0') return 0;
    const char *p = path;
    while (1) {
        const char *colon = strchr(p, ':');
        size_t n = colon ? (size_t)(colon - p) : strlen(p);
        char candidate[PATH_MAX];
        int written;
        if (n == 0)
            written = snprintf(candidate, sizeof candidate, "./%s", name);
        else
            written = snprintf(candidate, sizeof candidate, "%.*s/%s", (int)n, p, name);
        if (written > 0 && (size_t)written < sizeof candidate && access(candidate, F_OK) == 0 &&
            accept_executable("PATH", candidate, lib_version, 1, tried)) {
            return copy_str(out, size, candidate) == 0;
        }
        if (colon == NULL) break;
        p = colon + 1;
    }
    return 0;
}

/* The executable of the installation that provides the loaded libpython (prefix/lib/libpython*
 * or prefix/lib/<multiarch>/libpython* next to prefix/bin/pythonX.Y).  Pairing libpython with an
 * executable of another installation makes CPython use a foreign stdlib, which can lack modules
 * that the other build compiled in (e.g. math). */
static int find_sibling_executable(const char *lib_path, const char *lib_version, char *out,
                                   size_t size, msgbuf *tried)
{
    char dir[PATH_MAX];
    if (lib_path[0] != '/' || realpath(lib_path, dir) == NULL) return 0;
    dirname_inplace(dir);
    for (int level = 0; level < 3 && strcmp(dir, "/") != 0; level++) {
        dirname_inplace(dir); /* candidate prefix */
        const char *names[2] = {lib_version, "3"};
        for (int i = 0; i < 2; i++) {
            if (names[i][0] == '\0') continue;
            char candidate[PATH_MAX + 32];
            snprintf(candidate, sizeof candidate, "%s/bin/python%s", strcmp(dir, "/") ? dir : "",
                     names[i]);
            if (access(candidate, F_OK) == 0 &&
                accept_executable("libpython's installation", candidate, lib_version, 1, tried))
                return copy_str(out, size, candidate) == 0;
        }
    }
    return 0;
}

static void append_hint(msgbuf *m, const runtime_record *rec)
{
    struct stat st;
    const char *version = rec->version[0] ? rec->version : "3.X";
    char example[PATH_MAX + 32];
    if (rec->libpython[0] != '\0' && stat(rec->libpython, &st) == 0)
        snprintf(example, sizeof example, "for example %s", rec->libpython);
    else
        snprintf(example, sizeof example, "a libpython%s.so.1.0; the FMU was built with Python %s",
                 version, version);
    msg_add(m,
            "\nTo fix: set RUBCOSIM_LIBPYTHON to the full path of a shared libpython (%s) and "
            "RUBCOSIM_PYTHON to the Python executable whose environment has the FMU's "
            "dependencies (for example the venv's bin/python).",
            example);
}

/* Make sure an initialised interpreter exists in this process.  Returns 0 on success; on failure
 * `err` holds a message for the user.  `info` collects notes logged on success. */
/* The modules every FMU imports beyond the standard library.  Checked right after starting
 * Python, so that a missing one is named in one message (pythonfmu reports an import error only
 * with logging on, and as a traceback). */
static const char *const REQUIRED_MODULES[] = {"numpy", "scipy"};

/* Write the required modules the running interpreter cannot import into `out` (comma
 * separated); returns how many.  Takes and releases the GIL. */
static int missing_modules(char *out, size_t size)
{
    typedef int (*gil_ensure_t)(void);
    typedef void (*gil_release_t)(int);
    typedef void *(*import_t)(const char *);
    typedef void (*void_t)(void);
    typedef void (*decref_t)(void *);
    gil_ensure_t ensure = (gil_ensure_t)dlsym(RTLD_DEFAULT, "PyGILState_Ensure");
    gil_release_t release = (gil_release_t)dlsym(RTLD_DEFAULT, "PyGILState_Release");
    import_t import = (import_t)dlsym(RTLD_DEFAULT, "PyImport_ImportModule");
    void_t clear = (void_t)dlsym(RTLD_DEFAULT, "PyErr_Clear");
    decref_t decref = (decref_t)dlsym(RTLD_DEFAULT, "Py_DecRef");
    out[0] = '\0';
    if (!ensure || !release || !import || !clear || !decref) return 0; /* cannot check */
    int count = 0;
    int gil = ensure();
    for (size_t i = 0; i < sizeof REQUIRED_MODULES / sizeof REQUIRED_MODULES[0]; i++) {
        void *module = import(REQUIRED_MODULES[i]);
        if (module != NULL) {
            decref(module);
            continue;
        }
        clear();
        size_t used = strlen(out);
        snprintf(out + used, size - used, "%s%s", count ? ", " : "", REQUIRED_MODULES[i]);
        count++;
    }
    release(gil);
    return count;
}

static int ensure_python(const char *resources, msgbuf *err, msgbuf *info, int *warn)
{
    /* 1. Python already in the process (Python host, or a tool embedding Python). */
    py_is_initialized_t host_is_init = (py_is_initialized_t)dlsym(RTLD_DEFAULT, "Py_IsInitialized");
    if (host_is_init != NULL && host_is_init()) {
        msg_add(info, "rubcosim FMU loader: Python is already running in this process.");
        copy_str(g_python_desc, sizeof g_python_desc, "the Python already running in the process");
        return 0;
    }

    runtime_record rec;
    read_runtime_record(resources, &rec);

    py_api api;
    char loaded[PATH_MAX] = "";
    msgbuf tried;
    tried.len = 0;
    tried.text[0] = '\0';

    if (host_is_init != NULL && resolve_py_api(RTLD_DEFAULT, &api) == NULL) {
        /* libpython is linked into the process but not initialised: it must be that one, any
         * other copy would not be the one the export library binds to. */
        copy_str(loaded, sizeof loaded, "(libpython already present in the process)");
    } else {
        /* 2. Find libpython. */
        const char *env_lib = getenv("RUBCOSIM_LIBPYTHON");
        int ok = 0;
        if (env_lib != NULL && env_lib[0] != '\0') {
            ok = try_libpython("RUBCOSIM_LIBPYTHON=", env_lib, &api, &tried, loaded,
                               sizeof loaded);
            if (!ok) *warn = 1;
        }
        if (!ok && !rec.found) {
            msg_add(&tried, "\n  - runtime record %s: %s", rec.file[0] ? rec.file : "(none)",
                    resources ? "missing or unreadable" : "no fmuResourceLocation given");
        }
        if (!ok) ok = try_libpython("recorded libpython", rec.libpython, &api, &tried, loaded,
                                    sizeof loaded);
        if (!ok) ok = try_libpython("recorded soname", rec.soname, &api, &tried, loaded,
                                    sizeof loaded);
        if (!ok) {
            char names[16][64];
            int count = 0;
            if (rec.version[0] != '\0') {
                snprintf(names[count++], sizeof names[0], "libpython%s.so.1.0", rec.version);
                snprintf(names[count++], sizeof names[0], "libpython%s.so", rec.version);
            } else {
                static const char *const versions[] = {"3.13", "3.12", "3.11", "3.10", "3.9"};
                for (size_t i = 0; i < sizeof versions / sizeof versions[0]; i++)
                    snprintf(names[count++], sizeof names[0], "libpython%s.so.1.0", versions[i]);
            }
            snprintf(names[count++], sizeof names[0], "libpython3.so");
            for (int i = 0; i < count && !ok; i++) {
                if (strcmp(names[i], rec.soname) == 0) continue;
                ok = try_libpython("soname", names[i], &api, &tried, loaded, sizeof loaded);
            }
        }
        if (!ok) {
            msg_add(err, "rubcosim FMU loader: no usable libpython was found, so Python cannot "
                         "be started for this FMU. Tried:%s%s", env_lib && env_lib[0] ? "" :
                         "\n  - RUBCOSIM_LIBPYTHON: not set", tried.text);
            append_hint(err, &rec);
            return -1;
        }
    }

    if (api.is_initialized()) { /* e.g. loaded RTLD_LOCAL by the host and already running */
        msg_add(info, "rubcosim FMU loader: Python (%s) is already initialised.", loaded);
        copy_str(g_python_desc, sizeof g_python_desc, "the Python already running in the process");
        return 0;
    }

    char lib_version[32] = "";
    if (major_minor(api.get_version(), lib_version, sizeof lib_version) != 0) lib_version[0] = 0;

    /* 3. Choose the program name: it decides sys.prefix, the venv and site-packages. */
    char exe[PATH_MAX] = "";
    const char *env_exe = getenv("RUBCOSIM_PYTHON");
    if (env_exe != NULL && env_exe[0] != '\0') {
        if (accept_executable("RUBCOSIM_PYTHON=", env_exe, lib_version, 0, &tried))
            copy_str(exe, sizeof exe, env_exe);
        else
            *warn = 1;
    }
    if (exe[0] == '\0' && rec.executable[0] != '\0') {
        if (accept_executable("recorded executable", rec.executable, lib_version, 0, &tried))
            copy_str(exe, sizeof exe, rec.executable);
        else
            *warn = 1; /* the build's interpreter is gone: say which one replaces it, and why */
    }
    if (!rec.found) {
        *warn = 1;
        msg_add(&tried, "\n  - runtime record %s: %s, so the build's interpreter is unknown",
                rec.file[0] ? rec.file : "(none)",
                resources ? "missing or unreadable" : "no fmuResourceLocation given");
    }
    char lib_path[PATH_MAX] = "";
    Dl_info lib_info;
    if (dladdr((void *)api.is_initialized, &lib_info) != 0 && lib_info.dli_fname != NULL)
        copy_str(lib_path, sizeof lib_path, lib_info.dli_fname);
    if (exe[0] == '\0')
        find_sibling_executable(lib_path, lib_version, exe, sizeof exe, &tried);
    if (exe[0] == '\0' && lib_version[0] != '\0') {
        char name[64];
        snprintf(name, sizeof name, "python%s", lib_version);
        find_on_path(name, lib_version, exe, sizeof exe, &tried);
    }
    if (exe[0] == '\0') find_on_path("python3", lib_version, exe, sizeof exe, &tried);

    if (exe[0] == '\0') {
        *warn = 1;
        msg_add(info,
                "rubcosim FMU loader: no suitable Python executable found; starting Python %s "
                "from %s with its built-in prefix, so no virtual environment is used. Notes:%s",
                lib_version, loaded, tried.text);
        msg_add(info, "\nSet RUBCOSIM_PYTHON to the venv's python to use its site-packages.");
    } else {
        wchar_t *program = api.decode_locale(exe, NULL);
        if (program == NULL) {
            msg_add(err, "rubcosim FMU loader: Py_DecodeLocale failed for the executable path %s.",
                    exe);
            append_hint(err, &rec);
            return -1;
        }
        api.set_program_name(program); /* must stay valid: intentionally never freed */
        msg_add(info, "rubcosim FMU loader: started Python %s from %s as %s.", lib_version,
                lib_path[0] ? lib_path : loaded, exe);
        if (*warn) msg_add(info, " Notes:%s", tried.text);
    }

    /* 4. Start the interpreter without signal handlers (the host owns signals) and release the
     * GIL: pythonfmu takes it with PyGILState_Ensure on every call, from any thread. */
    api.initialize_ex(0);
    if (!api.is_initialized()) {
        msg_add(err, "rubcosim FMU loader: Py_InitializeEx failed (libpython %s, program %s).",
                loaded, exe[0] ? exe : "(default)");
        append_hint(err, &rec);
        return -1;
    }
    api.save_thread();
    snprintf(g_python_desc, sizeof g_python_desc, "libpython %s, executable %s",
             lib_path[0] ? lib_path : loaded, exe[0] ? exe : "(built-in prefix)");
    char missing[256] = "";
    if (missing_modules(missing, sizeof missing) > 0) {
        msg_add(err,
                "rubcosim FMU loader: the Python it started (%s) cannot import %s, which the FMU "
                "needs. Set RUBCOSIM_PYTHON to the python of an environment that has them, and "
                "RUBCOSIM_LIBPYTHON to that Python's shared libpython if it is another build. "
                "How it chose this one:%s",
                g_python_desc, missing, tried.text);
        return -1;
    }
    return 0;
}

/* pythonfmu 0.7 keeps its PyState in a static std::shared_ptr and also resets that pointer from
 * an __attribute__((destructor)) function.  When the library is still loaded at process exit (as
 * it always is here, RTLD_NODELETE), exit() first runs the C++ static destructors, freeing the
 * PyState, and only then the destructor function, which releases the freed block again: heap
 * corruption, typically reported as "free(): corrupted unsorted chunks" at exit.  Calling
 * finalizePythonInterpreter earlier, while the shared_ptr is alive, leaves it empty so the later
 * calls are no-ops.  Python itself is not finalised by this: the interpreter was running before
 * pythonfmu's PyState was created, so its worker thread has nothing to tear down.  The handler
 * also runs if the host dlclose()s this shim (glibc runs a DSO's atexit handlers then). */
static void rcs_before_exit(void)
{
    if (g_finalize != NULL) g_finalize();
}

/* Load the pythonfmu export library stored next to this shim and fill g_api. */
static int load_export_library(const char *resources, msgbuf *err)
{
    char path[PATH_MAX];
    if (g_self_path[0] != '\0') {
        char dir[PATH_MAX];
        copy_str(dir, sizeof dir, g_self_path);
        dirname_inplace(dir);
        const char *base = strrchr(g_self_path, '/');
        base = base ? base + 1 : g_self_path;
        size_t stem = strlen(base);
        if (stem > 3 && strcmp(base + stem - 3, ".so") == 0) stem -= 3;
        if (snprintf(path, sizeof path, "%s/%.*s_pythonfmu_export.so", dir, (int)stem, base) >=
            (int)sizeof path) {
            msg_add(err, "rubcosim FMU loader: export library path too long.");
            return -1;
        }
    } else {
        msg_add(err, "rubcosim FMU loader: cannot determine the location of the loader library "
                     "(dladdr failed); resources at %s.", resources ? resources : "(unknown)");
        return -1;
    }

    dlerror();
    /* RTLD_NODELETE: pythonfmu's unload hook would otherwise run at an arbitrary dlclose. */
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (h == NULL) {
        const char *e = dlerror();
        msg_add(err, "rubcosim FMU loader: cannot load the pythonfmu export library %s: %s", path,
                e ? e : "dlopen failed");
        return -1;
    }
    int missing = 0;
#define RCS_RESOLVE(name)                                                                        \
    do {                                                                                         \
        *(void **)(&g_api.name) = dlsym(h, #name);                                               \
        if (g_api.name == NULL) {                                                                \
            msg_add(err, "%s%s", missing++ ? ", " : "rubcosim FMU loader: export library lacks ", \
                    #name);                                                                      \
        }                                                                                        \
    } while (0)
    RCS_RESOLVE(fmi2GetTypesPlatform);
    RCS_RESOLVE(fmi2GetVersion);
    RCS_RESOLVE(fmi2Instantiate);
    RCS_RESOLVE(fmi2FreeInstance);
#define RCS_RESOLVE_X(name, params, args) RCS_RESOLVE(name);
#define RCS_RESOLVE_V(name, params, args, type) RCS_RESOLVE(name);
    RCS_STATUS_FUNCTIONS(RCS_RESOLVE_X)
    RCS_CHECKED_STATUS_FUNCTIONS(RCS_RESOLVE_X)
    RCS_VALUE_FUNCTIONS(RCS_RESOLVE_V)
#undef RCS_RESOLVE_V
#undef RCS_RESOLVE_X
#undef RCS_RESOLVE
    if (missing) {
        msg_add(err, " (%s).", path);
        memset(&g_api, 0, sizeof g_api);
        return -1;
    }
    *(void **)(&g_finalize) = dlsym(h, "finalizePythonInterpreter");
    /* Registered after the export library's static constructors ran, so it runs before their
     * destructors (exit handlers are LIFO); see rcs_before_exit. */
    if (atexit(rcs_before_exit) != 0) g_finalize = NULL;
    return 0;
}

__attribute__((constructor)) static void rcs_on_load(void)
{
    /* Record our own absolute path now: the host may pass a relative path and chdir later. */
    Dl_info info;
    if (dladdr((void *)&rcs_on_load, &info) != 0 && info.dli_fname != NULL) {
        char resolved[PATH_MAX];
        if (realpath(info.dli_fname, resolved) != NULL)
            copy_str(g_self_path, sizeof g_self_path, resolved);
        else
            copy_str(g_self_path, sizeof g_self_path, info.dli_fname);
    }
}

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
typedef struct {
    fmi2CallbackFunctions callbacks; /* what pythonfmu gets; its componentEnvironment is this */
    const fmi2CallbackFunctions *host;
    int logging_on; /* the host's */
} rcs_env;

static __thread int t_error_logged;

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

static rcs_env *routed_callbacks(const fmi2CallbackFunctions *host, fmi2Boolean loggingOn)
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
static fmi2Status answer(fmi2Status status)
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

static void remember_instance(fmi2Component c, const fmi2CallbackFunctions *functions,
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
static rcs_env *forget_instance(fmi2Component c)
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
static void log_refusal(fmi2Component c, const char *text)
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
    if (c == NULL && !loggingOn) {
        /* pythonfmu reports its Python exceptions only when logging is on. */
        char text[sizeof g_python_desc + 512];
        snprintf(text, sizeof text,
                 "rubcosim FMU loader: pythonfmu's fmi2Instantiate failed (Python: %s). Its error "
                 "details are only logged with loggingOn=fmi2True. If a module is missing, set "
                 "RUBCOSIM_PYTHON to the python of the environment that has the FMU's "
                 "dependencies.",
                 g_python_desc);
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
    int found = 0;
    pthread_mutex_lock(&g_lock);
    for (size_t k = 0; k < RCS_MAX_INSTANCES; k++) {
        if (g_inst[k].c == c && g_inst[k].env != NULL) {
            g_inst[k].env->logging_on = loggingOn;
            found = 1;
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
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
