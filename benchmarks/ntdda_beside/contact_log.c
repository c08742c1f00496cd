/*
 * contact_log.c: ntdda's contact states, solve by solve, for benchmarks/quiet16.py.  Linked with
 * step_timer.c against ntdda's library (build.sh) and the option -Wl,--wrap=df22: ntdda's analysis
 * loop calls df22 (its contact judge) after every open-close solve, and the call goes through
 * __wrap_df22 below, which runs ntdda's df22 and then writes, when $NTDDA_CONTACT_LOG names a
 * file, one line a contact:
 *
 *     step solve contact type block_vertex block_edge previous current tension pendist shear dt
 *
 * (type 0 vertex-edge, 1 vertex-vertex; blocks in ntdda's numbering from 1; states 0 open,
 * 1 sliding, 2 locked, 3 the other VV line, closed; pendist the normal distance of the judged line,
 * negative inside, and shear the shear displacement, both in length units), and at the first solve
 * of a step one line "C step x1 y1 x2 y2 ..." with every block's area centroid at the step's start.
 * No ntdda file is changed.
 */
#include <stdio.h>
#include <stdlib.h>

#include "dda.h"
#include "contacts.h"
#include "analysis.h"
#include "geometrydata.h"
#include "analysisdata.h"

void __real_df22(Geometrydata *gd, Analysisdata *ad, Contacts *ctacts, int *k1, TransMap transmap);

static FILE *contact_log;
static int log_opened;

void block_centroid(Geometrydata *gd, int b, double c[2]);  /* step_timer.c */

static void centroids(FILE *f, Geometrydata *gd, int step) {
    int b;
    fprintf(f, "C %d", step);
    for (b = 1; b <= gd->nBlocks; b++) {
        double c[2];
        block_centroid(gd, b, c);
        fprintf(f, " %.12g %.12g", c[0], c[1]);
    }
    fprintf(f, "\n");
}

void __wrap_df22(Geometrydata *gd, Analysisdata *ad, Contacts *ctacts, int *k1, TransMap transmap) {
    int c, solve = ad->m9;  /* ntdda counts the solve before it judges: 1 at a step's first */
    __real_df22(gd, ad, ctacts, k1, transmap);
    if (!log_opened) {
        const char *path = getenv("NTDDA_CONTACT_LOG");
        log_opened = 1;
        if (path) contact_log = fopen(path, "w");
    }
    if (!contact_log) return;
    if (solve == 1) centroids(contact_log, gd, ad->cts);
    {
        int **list = get_contacts(ctacts), **locks = get_locks(ctacts);
        double **lengths = get_contact_lengths(ctacts);
        for (c = 1; c <= gd->nContacts; c++)
            fprintf(contact_log, "%d %d %d %d %d %d %d %d %d %.9e %.9e %.9e\n", ad->cts, solve, c, list[c][0],
                    gd->nn0[list[c][1]], gd->nn0[list[c][2]], locks[c][1], locks[c][2], locks[c][0],
                    lengths[c][0], lengths[c][1], ad->delta_t);
    }
}
