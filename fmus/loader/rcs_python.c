/* Starting Python in the process (or using the running one) and loading the pythonfmu export library. */
#include "rcs_shim.h"

rcs_api g_api;
pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
int g_ready = 0;
void (*g_finalize)(void);
char g_self_path[PATH_MAX];
char g_python_desc[2 * PATH_MAX + 64];

/* Make sure an initialised interpreter exists in this process.  Returns 0 on success; on failure
 * `err` holds a message for the user.  `info` collects notes logged on success. */
int ensure_python(const char *resources, msgbuf *err, msgbuf *info, int *warn)
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
int load_export_library(const char *resources, msgbuf *err)
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
