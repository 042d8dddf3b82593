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
 * Inside one folder, includes must also form no cycle between its modules (a module is a file's name without
 * .c/.h: daemon/acquire.c and daemon/acquire.h are the module daemon/acquire), so that its flow stays one-way:
 *
 *     int cycles = layering_cycles(".", "daemon", report, sizeof report, NULL);
 *     // cycles > 0: report lists each as "cycle: a.c includes b.h (line 3); b.h includes a.h (line 9)"
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

/* Check the includes between the modules of folder `dir` under root ("dir/x.h" included by dir/y.c or dir/y.h;
 * a module including its own header does not count). Returns the number of cycles found (0: one-way; each
 * found once, from its edge back to a module still open in a depth-first walk) and writes each to report, one a
 * line, naming the including file, the included header and the line of each include along it; or -errno when the
 * folder cannot be read, -E2BIG above 512 modules. `modules` (nullable) receives how many modules were seen. */
int layering_cycles(const char *root, const char *dir, char *report, size_t report_size, int *modules);

#endif
