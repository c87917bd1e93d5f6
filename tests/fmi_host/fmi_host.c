/*
 * Minimal FMI 2.0 co-simulation host for tests: no Python anywhere in this process.
 *
 * usage: fmi_host <unzipped-fmu-dir> <model-identifier> <guid>
 *                 [--set VR=VALUE]... [--get VR]... [--steps N] [--step H] [--start T]
 *
 * Loads <dir>/binaries/linux64/<id>.so with RTLD_NOW|RTLD_LOCAL (like typical tools), sets the
 * real inputs/parameters given with --set before initialisation, runs N fmi2DoStep calls and
 * after each prints "t,v1,v2,..." (%.17g) for the --get value references.  Log messages go to
 * stderr.  Any non-OK status ends the run with a message and a nonzero exit code.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;

typedef struct {
    void (*logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*instantiate_t)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                       const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*setup_t)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean,
                              fmi2Real);
typedef fmi2Status (*simple_t)(fmi2Component);
typedef fmi2Status (*reals_t)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*setreals_t)(fmi2Component, const fmi2ValueReference *, size_t,
                                 const fmi2Real *);
typedef fmi2Status (*dostep_t)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef void (*free_t)(fmi2Component);

static const char *status_name(fmi2Status s)
{
    static const char *names[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};
    return (s >= 0 && s <= 5) ? names[s] : "?";
}

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s][%s][%s] ", instance ? instance : "", status_name(status),
            category ? category : "");
    vfprintf(stderr, message, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static void *must_sym(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (f == NULL) {
        fprintf(stderr, "fmi_host: symbol %s missing: %s\n", name, dlerror());
        exit(2);
    }
    return f;
}

#define CHECK(call, what)                                                                        \
    do {                                                                                         \
        fmi2Status st_ = (call);                                                                 \
        if (st_ != fmi2OK) {                                                                     \
            fprintf(stderr, "fmi_host: %s returned %s\n", what, status_name(st_));              \
            return 3;                                                                            \
        }                                                                                        \
    } while (0)

#define MAX_VARS 64

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr,
                "usage: %s <unzipped-fmu-dir> <model-identifier> <guid> [--set VR=VALUE]... "
                "[--get VR]... [--steps N] [--step H] [--start T]\n",
                argv[0]);
        return 2;
    }
    const char *dir = argv[1], *ident = argv[2], *guid = argv[3];
    fmi2ValueReference set_vr[MAX_VARS], get_vr[MAX_VARS];
    fmi2Real set_val[MAX_VARS], got[MAX_VARS];
    size_t nset = 0, nget = 0;
    long steps = 10;
    double h = 0.01, t0 = 0.0;

    for (int i = 4; i < argc; i++) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (v == NULL) {
            fprintf(stderr, "fmi_host: option %s needs a value\n", a);
            return 2;
        }
        if (strcmp(a, "--set") == 0) {
            const char *eq = strchr(v, '=');
            if (eq == NULL || nset >= MAX_VARS) {
                fprintf(stderr, "fmi_host: bad --set %s (expected VR=VALUE)\n", v);
                return 2;
            }
            set_vr[nset] = (fmi2ValueReference)strtoul(v, NULL, 10);
            set_val[nset++] = strtod(eq + 1, NULL);
        } else if (strcmp(a, "--get") == 0) {
            if (nget >= MAX_VARS) return 2;
            get_vr[nget++] = (fmi2ValueReference)strtoul(v, NULL, 10);
        } else if (strcmp(a, "--steps") == 0) {
            steps = strtol(v, NULL, 10);
        } else if (strcmp(a, "--step") == 0) {
            h = strtod(v, NULL);
        } else if (strcmp(a, "--start") == 0) {
            t0 = strtod(v, NULL);
        } else {
            fprintf(stderr, "fmi_host: unknown option %s\n", a);
            return 2;
        }
        i++;
    }

    char lib_path[8192], resources[8192];
    snprintf(lib_path, sizeof lib_path, "%s/binaries/linux64/%s.so", dir, ident);
    /* URI as most tools build it; spaces percent-encoded */
    char *r = resources;
    r += snprintf(resources, sizeof resources, "file://");
    for (const char *p = dir; *p && r < resources + sizeof resources - 16; p++) {
        if (*p == ' ') {
            memcpy(r, "%20", 3);
            r += 3;
        } else {
            *r++ = *p;
        }
    }
    snprintf(r, sizeof resources - (size_t)(r - resources), "/resources");

    void *lib = dlopen(lib_path, RTLD_NOW | RTLD_LOCAL);
    if (lib == NULL) {
        fprintf(stderr, "fmi_host: cannot load %s: %s\n", lib_path, dlerror());
        return 2;
    }
    instantiate_t instantiate = (instantiate_t)must_sym(lib, "fmi2Instantiate");
    setup_t setup = (setup_t)must_sym(lib, "fmi2SetupExperiment");
    simple_t enter = (simple_t)must_sym(lib, "fmi2EnterInitializationMode");
    simple_t exitinit = (simple_t)must_sym(lib, "fmi2ExitInitializationMode");
    simple_t terminate = (simple_t)must_sym(lib, "fmi2Terminate");
    setreals_t set_real = (setreals_t)must_sym(lib, "fmi2SetReal");
    reals_t get_real = (reals_t)must_sym(lib, "fmi2GetReal");
    dostep_t do_step = (dostep_t)must_sym(lib, "fmi2DoStep");
    free_t free_instance = (free_t)must_sym(lib, "fmi2FreeInstance");

    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("instance", fmi2CoSimulation, guid, resources, &callbacks, 0, 0);
    if (c == NULL) {
        fprintf(stderr, "fmi_host: fmi2Instantiate returned NULL\n");
        dlclose(lib);
        return 4;
    }
    CHECK(setup(c, 0, 0.0, t0, 0, 0.0), "fmi2SetupExperiment");
    if (nset > 0) CHECK(set_real(c, set_vr, nset, set_val), "fmi2SetReal");
    CHECK(enter(c), "fmi2EnterInitializationMode");
    CHECK(exitinit(c), "fmi2ExitInitializationMode");

    for (long k = 0; k < steps; k++) {
        double t = t0 + (double)k * h;
        CHECK(do_step(c, t, h, 1), "fmi2DoStep");
        if (nget > 0) CHECK(get_real(c, get_vr, nget, got), "fmi2GetReal");
        printf("%.17g", t0 + (double)(k + 1) * h);
        for (size_t j = 0; j < nget; j++) printf(",%.17g", got[j]);
        printf("\n");
    }
    fflush(stdout);
    CHECK(terminate(c), "fmi2Terminate");
    free_instance(c);
    dlclose(lib);
    return 0;
}
