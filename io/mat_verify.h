/* io/mat_verify.h — integrity of a MATLAB v5 .mat file before libmatio reads it.
 *
 * libmatio trusts a file: it inflates a compressed variable only as far as the data it wants and never reaches the
 * zlib stream's adler32 trailer, it stops quietly at a truncated element, and a flipped size byte becomes a
 * different array. A byte flipped on disk then gives a different reconstruction and exit 0 (measured: 13 of 17
 * flips in drop40_cacti.mat passed). This module checks every check the format carries, and the sizes it implies:
 *
 *   - the header: byte-order mark "IM" (or "MI" for big-endian files) and version 0x0100 (v7.3's 0x0200 is an
 *     HDF5 file: left to the HDF5 library and its own checksums; the 116 bytes of descriptive text are not data
 *     and are not checked);
 *   - the element chain: every top-level element is miMATRIX (14) or miCOMPRESSED (15), and the last one ends
 *     exactly at the end of the file (nothing truncated, nothing appended);
 *   - miCOMPRESSED: the whole zlib stream is inflated (in 64 KiB pieces, nothing kept) and must end exactly at the
 *     element's end with zlib's adler32 verified — so every change to a compressed variable is detected;
 *   - inside every variable: array flags, dimensions, name and, for numeric arrays, a real (and imaginary) part
 *     of exactly prod(dims) × the element size of its stored type, the subelements filling the matrix exactly.
 *
 * An uncompressed variable carries no checksum: a flip in its numbers cannot be told from data, only its structure
 * is checked. Errors: SCI_EFORMAT with a message naming the file, the byte offset and what is wrong; -errno when
 * the file cannot be read. Cost: one sequential read and one inflate of the file (drop40: 1.7 MB in ~20 ms).
 * Reentrant.
 */
#ifndef SCICAP_IO_MAT_VERIFY_H
#define SCICAP_IO_MAT_VERIFY_H

#include "base/error.h"

int sci_mat_verify(const char *path, sci_error *err);

#endif
