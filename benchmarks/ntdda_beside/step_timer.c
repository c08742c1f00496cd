/*
 * step_timer.c: run one ntdda analysis (a DDAML geometry + analysis file pair) headless and time
 * each of its steps.  Our own driver, linked against the library ntdda's CMake build makes
 * (libdda.a); build it with build.sh beside this file.  No ntdda source is part of it.
 *
 *     step_timer GEOMETRY.geo ANALYSIS.ana [SKIP]
 *
 * Prints one JSON line on stdout: the step count, ntdda's time step and contact penalty, its
 * open-close iterations per step, the wall time of a step (median and mean of the steps after the
 * first SKIP, default 10: step 1 also writes K to a file), the CPU time of a step (mean over the
 * same steps), the cost of the per-step clock reading and
 * each block's area centroid at the end.  ntdda writes its usual output files under ./output/ of
 * the working directory (its measured points every step, as a user's run does).
 *
 * Two hooks, neither a change to ntdda's files:
 * - the step clock: ntdda's analysis loop calls display() once before the first step and once at
 *   the end of every step; the link option -Wl,--wrap=display routes those calls through
 *   __wrap_display below, which reads the clocks and goes on to ntdda's display();
 * - rand(): ntdda's point-in-block ray casting expects the Microsoft C library's generator
 *   (RAND_MAX = 32767; with glibc's 2^31 - 1 its ray direction is NaN and block cutting never
 *   returns).  rand()/srand() here are that generator's published recurrence, which the
 *   executable's own definitions give to the library in place of the C library's.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "dda.h"
#include "ddafile.h"
#include "geometrydata.h"
#include "analysisdata.h"

/* ntdda's library declares this global extern and leaves its definition to the program. */
Filepaths filepath;

static unsigned long lcg_state = 1;

int rand(void) {
    lcg_state = (lcg_state * 214013UL + 2531011UL) & 0xffffffffUL;
    return (int)((lcg_state >> 16) & 0x7fff);
}

void srand(unsigned int seed) { lcg_state = seed; }

static double *step_wall, cpu_from, cpu_to;
static int *step_oc;
static int n_recorded, capacity, last_n9, skip = 10;
static double last_wall;

static double now(clockid_t clock) {
    struct timespec t;
    clock_gettime(clock, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void __real_display(Geometrydata *gd, Analysisdata *ad);

/* Each step's wall time from one reading of the monotonic clock (a few tens of ns); the CPU
 * clock (a system call of about a microsecond, 5-10 % of a one-block step) is read twice only:
 * at the end of step SKIP and at the end of the last step. */
void __wrap_display(Geometrydata *gd, Analysisdata *ad) {
    double wall = now(CLOCK_MONOTONIC);
    if (ad->cts >= 1 && n_recorded < capacity) {
        step_wall[n_recorded] = wall - last_wall;
        step_oc[n_recorded] = ad->n9 - last_n9;
        n_recorded++;
    }
    if (ad->cts == skip) cpu_from = now(CLOCK_PROCESS_CPUTIME_ID);
    if (ad->cts == ad->nTimeSteps) cpu_to = now(CLOCK_PROCESS_CPUTIME_ID);
    last_n9 = ad->n9;
    last_wall = wall;
    __real_display(gd, ad);
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(const double *v, int n) {
    double *s = malloc(sizeof(double) * (size_t)n), m;
    memcpy(s, v, sizeof(double) * (size_t)n);
    qsort(s, (size_t)n, sizeof(double), by_value);
    m = n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
    free(s);
    return m;
}

static double mean(const double *v, int n) {
    double s = 0.0;
    int i;
    for (i = 0; i < n; i++) s += v[i];
    return s / n;
}

/* The cost of one step's clock reading. */
/* Area centroid of block b's vertex loop (ntdda repeats the first vertex at its end); also
 * contact_log.c's. */
void block_centroid(Geometrydata *gd, int b, double c[2]) {
    int j, j0 = gd->vindex[b][1], j1 = gd->vindex[b][2];
    double a = 0.0, cx = 0.0, cy = 0.0;
    for (j = j0; j <= j1; j++) {
        int k = j < j1 ? j + 1 : j0;
        double x0 = gd->vertices[j][1], y0 = gd->vertices[j][2];
        double x1 = gd->vertices[k][1], y1 = gd->vertices[k][2];
        double w = x0 * y1 - x1 * y0;
        a += w;
        cx += (x0 + x1) * w;
        cy += (y0 + y1) * w;
    }
    c[0] = cx / (3.0 * a);
    c[1] = cy / (3.0 * a);
}

static double timer_cost(void) {
    double t0 = now(CLOCK_MONOTONIC), sink = 0.0;
    int i;
    for (i = 0; i < 100000; i++) sink += now(CLOCK_MONOTONIC);
    (void)sink;
    return (now(CLOCK_MONOTONIC) - t0) / 100000;
}

int main(int argc, char **argv) {
    DDA *dda;
    Geometrydata *gd;
    Analysisdata *ad;
    const char *geo, *ana, *base;
    char root[FNAME_BUFSIZE];
    int timed, i, b, oc_total = 0, oc_max = 0;
    double t0, c0, total_wall, total_cpu;

    if (argc < 3) {
        fprintf(stderr, "usage: %s GEOMETRY.geo ANALYSIS.ana [SKIP]\n", argv[0]);
        return 2;
    }
    if (argc > 3) skip = atoi(argv[3]);
    geo = argv[1];
    ana = argv[2];
    base = strrchr(ana, '/') ? strrchr(ana, '/') + 1 : ana;
    strncpy(root, base, sizeof(root) - 1);
    root[sizeof(root) - 1] = '\0';
    if (strrchr(root, '.')) *strrchr(root, '.') = '\0';

    dda = dda_new();
    gd = gdata_new();
    gd->display_error = dda_display_error;
    gd->display_warning = dda_display_warning;
    gdata_read_input_file(gd, (char *)geo);
    dda_set_geometrydata(dda, gd);
    ddacut(gd);

    ad = adata_new();
    ad->display_error = dda_display_error;
    ad->display_warning = dda_display_warning;
    adata_read_input_file(ad, (char *)ana, gd->nFPoints, gd->pointCount, gd->nLPoints);
    dda_set_analysisdata(dda, ad);
    if (gd->nBlocks <= 0 || ad->nTimeSteps <= skip) {
        fprintf(stderr, "step_timer: %d blocks, %d steps (need more than %d)\n", gd->nBlocks, ad->nTimeSteps, skip);
        return 1;
    }

    capacity = ad->nTimeSteps + 8;
    step_wall = calloc((size_t)capacity, sizeof(double));
    step_oc = calloc((size_t)capacity, sizeof(int));

    memset(&filepath, 0, sizeof(filepath));
    strncpy(filepath.gfile, geo, FNAME_BUFSIZE - 1);
    strncpy(filepath.afile, ana, FNAME_BUFSIZE - 1);
    strncpy(filepath.rootname, root, FNAME_BUFSIZE - 1);

    t0 = now(CLOCK_MONOTONIC);
    c0 = now(CLOCK_PROCESS_CPUTIME_ID);
    if (ddanalysis(dda, &filepath) != 1) {
        fprintf(stderr, "step_timer: ddanalysis failed\n");
        return 1;
    }
    total_wall = now(CLOCK_MONOTONIC) - t0;
    total_cpu = now(CLOCK_PROCESS_CPUTIME_ID) - c0;
    timed = n_recorded - skip;
    for (i = 0; i < n_recorded; i++) {
        oc_total += step_oc[i];
        if (step_oc[i] > oc_max) oc_max = step_oc[i];
    }

    printf("{\"blocks\": %d, \"steps\": %d, \"timed_steps\": %d, \"dt\": %.17g, \"penalty\": %.17g, "
           "\"w0\": %.17g, \"oc_per_step\": %.6f, \"oc_max\": %d, ",
           gd->nBlocks, n_recorded, timed, ad->delta_t, ad->contactpenalty, gd->w0,
           (double)oc_total / n_recorded, oc_max);
    printf("\"median_ms\": %.6g, \"mean_ms\": %.6g, \"mean_cpu_ms\": %.6g, "
           "\"first_step_ms\": %.6g, \"analysis_s\": %.6g, \"analysis_cpu_s\": %.6g, \"timer_us\": %.4g, ",
           1e3 * median(step_wall + skip, timed), 1e3 * mean(step_wall + skip, timed),
           1e3 * (cpu_to - cpu_from) / timed, 1e3 * step_wall[0],
           total_wall, total_cpu, 1e6 * timer_cost());
    printf("\"centroids\": [");
    for (b = 1; b <= gd->nBlocks; b++) {
        double c[2];
        block_centroid(gd, b, c);
        printf("%s[%.12g, %.12g]", b > 1 ? ", " : "", c[0], c[1]);
    }
    printf("]}\n");
    return 0;
}
