/* Small helpers of the rubcosim FMU loader shim: messages, paths, versions. */
#include "rcs_shim.h"

/* ------------------------------------------------------------------------------------------ */
/* Small helpers                                                                              */
/* ------------------------------------------------------------------------------------------ */



void msg_add(msgbuf *m, const char *fmt, ...)
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
void log_message(const fmi2CallbackFunctions *functions, fmi2String instanceName,
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
const char *label_sep(const char *label)
{
    size_t n = strlen(label);
    return (n > 0 && label[n - 1] == '=') ? "" : " ";
}

int copy_str(char *dst, size_t size, const char *src)
{
    size_t n = strlen(src);
    if (n >= size) return -1;
    memcpy(dst, src, n + 1);
    return 0;
}

int is_executable_file(const char *path)
{
    struct stat st;
    return path != NULL && path[0] != '\0' && stat(path, &st) == 0 && S_ISREG(st.st_mode) &&
           access(path, X_OK) == 0;
}

/* PATH may hold wrapper scripts (pyenv shims, conda wrappers); as program name these would
 * mislead CPython's prefix search, so the PATH fallback only accepts real ELF binaries. */
int is_elf_file(const char *path)
{
    unsigned char magic[4];
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return 0;
    ssize_t n = read(fd, magic, sizeof magic);
    close(fd);
    return n == 4 && magic[0] == 0x7f && magic[1] == 'E' && magic[2] == 'L' && magic[3] == 'F';
}

void dirname_inplace(char *path)
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
int major_minor(const char *version, char *out, size_t size)
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
int uri_to_path(const char *uri, char *out, size_t size)
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
