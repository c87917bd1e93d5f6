/* Finding the Python the FMU runs in: the runtime recorded at build time, libpython, a matching executable. */
#include "rcs_shim.h"

/* ------------------------------------------------------------------------------------------ */
/* Runtime record (<resources>/rubcosim_python.txt)                                           */
/* ------------------------------------------------------------------------------------------ */


void trim(char *s)
{
    size_t n = strlen(s);
    while (n > 0 && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ' || s[n - 1] == '\t'))
        s[--n] = '\0';
    size_t k = 0;
    while (s[k] == ' ' || s[k] == '\t') k++;
    if (k > 0) memmove(s, s + k, n - k + 1);
}

void read_runtime_record(const char *resources, runtime_record *rec)
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


/* Resolve the start-up functions from `handle` (RTLD_DEFAULT or a libpython handle).  Returns
 * the name of the first missing symbol, or NULL when all were found. */
const char *resolve_py_api(void *handle, py_api *api)
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
int try_libpython(const char *label, const char *candidate, py_api *api, msgbuf *tried,
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
int executable_version(const char *exe, char *out, size_t size)
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
int accept_executable(const char *label, const char *exe, const char *lib_version,
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

int find_on_path(const char *name, const char *lib_version, char *out, size_t size,
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
int find_sibling_executable(const char *lib_path, const char *lib_version, char *out,
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

void append_hint(msgbuf *m, const runtime_record *rec)
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

/* The modules every FMU imports beyond the standard library.  Checked right after starting
 * Python, so that a missing one is named in one message (pythonfmu reports an import error only
 * with logging on, and as a traceback). */
static const char *const REQUIRED_MODULES[] = {"numpy", "scipy"};

/* Write the required modules the running interpreter cannot import into `out` (comma
 * separated); returns how many.  Takes and releases the GIL. */
int missing_modules(char *out, size_t size)
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
