/* tests/helpers/layering.h — the layering check of docs/architecture.md: every #include "dir/file.h" in the tree
 * must point at the file's own folder or at a layer below it.
 *
 * A layer is a top-level folder with a rank; a file in folder F (the first component of its path) may include a
 * header of folder G only when G == F or rank(G) < rank(F). Folders of equal rank (io and drivers, daemon and cli)
 * know nothing of each other. Includes without a folder ("x.h") and system includes (<x.h>) are not checked.
 * Top-level folders that are not layers hold no source (docs, etc, systemd) or are build output: names starting
 * with "build" or "." are skipped; any other folder holding a .c/.h/.cpp is reported (a new folder must take its
 * place in the table), and so is an include of a folder that is not a layer.
 *
 *     char report[8192];
 *     int bad = layering_check(".", layering_tree, layering_tree_count, report, sizeof report);
 *     // bad < 0: -errno (the root could not be read); bad > 0: report lists "file:line: why", one a line
 *
 * Reads files only; allocates nothing that outlives the call; reentrant.
 */
#ifndef SCICAP_TESTS_HELPERS_LAYERING_H
#define SCICAP_TESTS_HELPERS_LAYERING_H

#include <stddef.h>

typedef struct layering_layer {
    const char *dir; /* top-level folder */
    int rank;        /* 0 = the bottom */
} layering_layer;

/* The tree's layers, bottom first (docs/architecture.md, "Layers"). */
extern const layering_layer layering_tree[];
extern const int layering_tree_count;

/* Check every .c, .h and .cpp under root. Returns the number of violations (0: clean) and writes them to report
 * ("path:line: message\n", path relative to root; truncated to report_size), or -errno if root cannot be walked.
 * `files` (nullable) receives how many files were read. */
int layering_check(const char *root, const layering_layer *layers, int n_layers, char *report, size_t report_size,
                   int *files);

#endif
