/* What a C or C++ engine does with vis5d: open a .v5d file, answer a few
 * cameras (as eye/forward/up/field of view, and as a view-projection
 * matrix), the change between two answers and what a box ahead may see.
 *
 *   cc -O2 -I include examples/c/query.c -L target/release -lvis5d_c \
 *      -Wl,-rpath,$PWD/target/release -o query
 *   ./query model.v5d
 *
 * Exits 0 when every call succeeded; prints the error and exits 1 else. */

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vis5d.h"

static int check(Vis5dStatus status, const char *what) {
    if (status != VIS5D_STATUS_OK) {
        fprintf(stderr, "%s failed (%d): %s\n", what, (int)status, vis5d_last_error());
        return 0;
    }
    return 1;
}

static size_t count(const uint64_t *set, size_t words) {
    size_t n = 0;
    for (size_t w = 0; w < words; w++) {
        for (uint64_t b = set[w]; b; b &= b - 1) {
            n++;
        }
    }
    return n;
}

/* OpenGL's perspective times a right-handed look-at, column-major. */
static void gl_view_projection(const float eye[3], const float f_in[3], const float up[3],
                               float vfov_radians, float aspect, float m[16]) {
    float f[3], s[3], u[3];
    float fl = sqrtf(f_in[0] * f_in[0] + f_in[1] * f_in[1] + f_in[2] * f_in[2]);
    for (int k = 0; k < 3; k++) f[k] = f_in[k] / fl;
    s[0] = f[1] * up[2] - f[2] * up[1];
    s[1] = f[2] * up[0] - f[0] * up[2];
    s[2] = f[0] * up[1] - f[1] * up[0];
    float sl = sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    for (int k = 0; k < 3; k++) s[k] /= sl;
    u[0] = s[1] * f[2] - s[2] * f[1];
    u[1] = s[2] * f[0] - s[0] * f[2];
    u[2] = s[0] * f[1] - s[1] * f[0];
    float view[16] = {0}, proj[16] = {0};
    for (int k = 0; k < 3; k++) {
        view[k * 4 + 0] = s[k];
        view[k * 4 + 1] = u[k];
        view[k * 4 + 2] = -f[k];
    }
    view[12] = -(s[0] * eye[0] + s[1] * eye[1] + s[2] * eye[2]);
    view[13] = -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]);
    view[14] = f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2];
    view[15] = 1.0f;
    float t = 1.0f / tanf(0.5f * vfov_radians), n = 0.1f, fr = 1000.0f;
    proj[0] = t / aspect;
    proj[5] = t;
    proj[10] = (fr + n) / (n - fr);
    proj[11] = -1.0f;
    proj[14] = 2.0f * fr * n / (n - fr);
    for (int c = 0; c < 4; c++) {
        for (int r = 0; r < 4; r++) {
            float v = 0.0f;
            for (int k = 0; k < 4; k++) v += proj[k * 4 + r] * view[c * 4 + k];
            m[c * 4 + r] = v;
        }
    }
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s FILE.v5d\n", argv[0]);
        return 2;
    }
    Vis5dPvs *pvs = NULL;
    if (!check(vis5d_open_path(argv[1], &pvs), "vis5d_open_path")) return 1;
    size_t objects = vis5d_object_count(pvs), words = vis5d_answer_words(pvs);
    double lo[3], hi[3];
    float up[3];
    if (!check(vis5d_view_box(pvs, lo, hi), "vis5d_view_box") || !check(vis5d_up(pvs, up), "vis5d_up")) {
        vis5d_free(pvs);
        return 1;
    }
    printf("vis5d %s: %s: %zu objects, view box (%g, %g, %g) .. (%g, %g, %g), up (%g, %g, %g)\n",
           vis5d_version(), argv[1], objects, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], up[0], up[1],
           up[2]);
    /* At least one word each: calloc(0) may give NULL. */
    size_t alloc_words = words ? words : 1;
    uint64_t *a = calloc(alloc_words, 8), *b = calloc(alloc_words, 8),
             *enter = calloc(alloc_words, 8), *leave = calloc(alloc_words, 8);
    int ok = a && b && enter && leave;
    double eye[3];
    for (int k = 0; k < 3; k++) eye[k] = 0.5 * (lo[k] + hi[k]);
    /* Two directions across the up axis. */
    int axis = up[0] != 0.0f ? 0 : up[1] != 0.0f ? 1 : 2;
    float across[2][3] = {{0}};
    across[0][(axis + 1) % 3] = 1.0f;
    across[1][(axis + 2) % 3] = 1.0f;
    Vis5dAnswer answer;
    for (int v = 0; ok && v < 4; v++) {
        float forward[3];
        for (int k = 0; k < 3; k++) forward[k] = (v < 2 ? 1.0f : -1.0f) * across[v % 2][k];
        ok = check(vis5d_query_camera(pvs, eye, forward, up, 60.0f, 16.0f / 9.0f, b, words, &answer),
                   "vis5d_query_camera");
        if (!ok) break;
        printf("camera %d looking (%g, %g, %g): %zu objects%s\n", v, forward[0], forward[1],
               forward[2], count(b, words),
               answer == VIS5D_ANSWER_EVERYTHING ? " (outside the view box: every object)" : "");
        if (v == 0) {
            for (size_t o = 0; o < objects; o++) {
                if (b[o / 64] >> (o % 64) & 1) printf("  %s\n", vis5d_object_name(pvs, o));
            }
        } else {
            ok = check(vis5d_delta(pvs, a, b, enter, leave, words), "vis5d_delta");
            if (ok) printf("  %zu entering, %zu leaving\n", count(enter, words), count(leave, words));
        }
        uint64_t *t = a;
        a = b;
        b = t;
    }
    if (ok) {
        float feye[3] = {(float)eye[0], (float)eye[1], (float)eye[2]}, m[16];
        gl_view_projection(feye, across[0], up, 1.0f, 1.5f, m);
        ok = check(vis5d_query_matrix(pvs, m, b, words, &answer), "vis5d_query_matrix");
        if (ok) printf("the same eye as an OpenGL view-projection matrix: %zu objects\n", count(b, words));
    }
    if (ok) {
        double bmin[3], bmax[3];
        for (int k = 0; k < 3; k++) {
            bmin[k] = eye[k] - 0.5;
            bmax[k] = eye[k] + 0.5;
        }
        ok = check(vis5d_query_box(pvs, bmin, bmax, b, words, &answer), "vis5d_query_box");
        if (ok) printf("prefetch, a 1 m box around the eye: %zu objects\n", count(b, words));
    }
    if (ok) {
        /* A bitset of the wrong size is refused, with a message. */
        Vis5dStatus s = vis5d_query_camera(pvs, eye, across[0], up, 60.0f, 1.0f, b, words + 1, NULL);
        ok = s == VIS5D_STATUS_SET_SIZE;
        printf("a bitset of %zu words: refused: %s\n", words + 1, vis5d_last_error());
    }
    free(a);
    free(b);
    free(enter);
    free(leave);
    vis5d_free(pvs);
    return ok ? 0 : 1;
}
