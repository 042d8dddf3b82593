/* tests/unit/test_cnn_weights.c — recon/cnn/weights.h: the FFDNet legacy .pth files read in C against values PyTorch
 * reads from them, small files with views, scalars and other dtypes, and damaged files that must be refused with a
 * message naming the file, the tensor or storage and the fault. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "base/error.h"
#include "base/file.h"
#include "recon/cnn/pickle.h"
#include "recon/cnn/weights.h"
#include "tests/helpers/testdata.h"

#define P "intermediate_dncnn.itermediate_dncnn."

/* What every legacy torch.save file begins with (the first 139 bytes of each file below): the magic number,
 * the protocol version and the sys_info dict (protocol_version 1001, little_endian, type_sizes short 2, int 4,
 * long 4). */
#define LEGACY_HEADER \
    0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19, 0x2e, 0x80, \
    0x02, 0x4d, 0xe9, 0x03, 0x2e, 0x80, 0x02, 0x7d, 0x71, 0x00, 0x28, 0x58, 0x10, 0x00, 0x00, 0x00, \
    0x70, 0x72, 0x6f, 0x74, 0x6f, 0x63, 0x6f, 0x6c, 0x5f, 0x76, 0x65, 0x72, 0x73, 0x69, 0x6f, 0x6e, \
    0x71, 0x01, 0x4d, 0xe9, 0x03, 0x58, 0x0d, 0x00, 0x00, 0x00, 0x6c, 0x69, 0x74, 0x74, 0x6c, 0x65, \
    0x5f, 0x65, 0x6e, 0x64, 0x69, 0x61, 0x6e, 0x71, 0x02, 0x88, 0x58, 0x0a, 0x00, 0x00, 0x00, 0x74, \
    0x79, 0x70, 0x65, 0x5f, 0x73, 0x69, 0x7a, 0x65, 0x73, 0x71, 0x03, 0x7d, 0x71, 0x04, 0x28, 0x58, \
    0x05, 0x00, 0x00, 0x00, 0x73, 0x68, 0x6f, 0x72, 0x74, 0x71, 0x05, 0x4b, 0x02, 0x58, 0x03, 0x00, \
    0x00, 0x00, 0x69, 0x6e, 0x74, 0x71, 0x06, 0x4b, 0x04, 0x58, 0x04, 0x00, 0x00, 0x00, 0x6c, 0x6f, \
    0x6e, 0x67, 0x71, 0x07, 0x4b, 0x04, 0x75, 0x75, 0x2e, 0x80, 0x02

/* Small legacy files written by torch 1.13 (/usr/bin/python3), bytes as saved:
 *
 *   import torch, collections, io
 *   def save(sd):
 *       b = io.BytesIO(); torch.save(sd, b, _use_new_zipfile_serialization=False); return b.getvalue()
 *   base = torch.arange(12, dtype=torch.float32) / 8 - 0.5
 *   sd = collections.OrderedDict()
 *   sd['module.conv.weight'] = base[:8].view(2, 1, 2, 2)       # storage of 12, offset 0
 *   sd['module.view'] = base[8:11]                             # the same storage, offset 8
 *   sd['module.bn.num_batches_tracked'] = torch.tensor(7)      # LongStorage, 0-d
 *   sd['module.d'] = torch.tensor([1.5], dtype=torch.float64)  # DoubleStorage
 *   sd['scalar'] = torch.tensor(2.25)                          # no prefix, 0-d
 *   sd._metadata = collections.OrderedDict([('', {'version': 1})])   # BUILD
 *   views = save(sd)
 *   transposed = save({'t': torch.arange(6.).view(2, 3).t()})        # strides (1, 3): not contiguous
 *   two = save({'w': torch.tensor([0.25, -1.0]), 'b': torch.tensor([3.0])})   # a plain dict, _rebuild_tensor_v2
 *
 * two: pickletools.dis shows storage 'b''s numel (BININT1 1) argument at offset 342; the key list puts its record
 * (int64 count) at 431, its data at 439; the file is 443 bytes (tests/fuzz/corpus/weights/two.pth is the same). */
static const unsigned char fixture_views[912] = {
    LEGACY_HEADER,
    0x63, 0x63, 0x6f, 0x6c, 0x6c, 0x65, 0x63, 0x74, 0x69, 0x6f, 0x6e, 0x73, 0x0a, 0x4f, 0x72, 0x64,
    0x65, 0x72, 0x65, 0x64, 0x44, 0x69, 0x63, 0x74, 0x0a, 0x71, 0x00, 0x29, 0x52, 0x71, 0x01, 0x28,
    0x58, 0x12, 0x00, 0x00, 0x00, 0x6d, 0x6f, 0x64, 0x75, 0x6c, 0x65, 0x2e, 0x63, 0x6f, 0x6e, 0x76,
    0x2e, 0x77, 0x65, 0x69, 0x67, 0x68, 0x74, 0x71, 0x02, 0x63, 0x74, 0x6f, 0x72, 0x63, 0x68, 0x2e,
    0x5f, 0x75, 0x74, 0x69, 0x6c, 0x73, 0x0a, 0x5f, 0x72, 0x65, 0x62, 0x75, 0x69, 0x6c, 0x64, 0x5f,
    0x74, 0x65, 0x6e, 0x73, 0x6f, 0x72, 0x5f, 0x76, 0x32, 0x0a, 0x71, 0x03, 0x28, 0x28, 0x58, 0x07,
    0x00, 0x00, 0x00, 0x73, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x71, 0x04, 0x63, 0x74, 0x6f, 0x72,
    0x63, 0x68, 0x0a, 0x46, 0x6c, 0x6f, 0x61, 0x74, 0x53, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x0a,
    0x71, 0x05, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x34, 0x39, 0x36,
    0x71, 0x06, 0x58, 0x03, 0x00, 0x00, 0x00, 0x63, 0x70, 0x75, 0x71, 0x07, 0x4b, 0x0c, 0x4e, 0x74,
    0x71, 0x08, 0x51, 0x4b, 0x00, 0x28, 0x4b, 0x02, 0x4b, 0x01, 0x4b, 0x02, 0x4b, 0x02, 0x74, 0x71,
    0x09, 0x28, 0x4b, 0x04, 0x4b, 0x04, 0x4b, 0x02, 0x4b, 0x01, 0x74, 0x71, 0x0a, 0x89, 0x68, 0x00,
    0x29, 0x52, 0x71, 0x0b, 0x74, 0x71, 0x0c, 0x52, 0x71, 0x0d, 0x58, 0x0b, 0x00, 0x00, 0x00, 0x6d,
    0x6f, 0x64, 0x75, 0x6c, 0x65, 0x2e, 0x76, 0x69, 0x65, 0x77, 0x71, 0x0e, 0x68, 0x03, 0x28, 0x28,
    0x68, 0x04, 0x68, 0x05, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x34,
    0x39, 0x36, 0x71, 0x0f, 0x68, 0x07, 0x4b, 0x0c, 0x4e, 0x74, 0x71, 0x10, 0x51, 0x4b, 0x08, 0x4b,
    0x03, 0x85, 0x71, 0x11, 0x4b, 0x01, 0x85, 0x71, 0x12, 0x89, 0x68, 0x00, 0x29, 0x52, 0x71, 0x13,
    0x74, 0x71, 0x14, 0x52, 0x71, 0x15, 0x58, 0x1d, 0x00, 0x00, 0x00, 0x6d, 0x6f, 0x64, 0x75, 0x6c,
    0x65, 0x2e, 0x62, 0x6e, 0x2e, 0x6e, 0x75, 0x6d, 0x5f, 0x62, 0x61, 0x74, 0x63, 0x68, 0x65, 0x73,
    0x5f, 0x74, 0x72, 0x61, 0x63, 0x6b, 0x65, 0x64, 0x71, 0x16, 0x68, 0x03, 0x28, 0x28, 0x68, 0x04,
    0x63, 0x74, 0x6f, 0x72, 0x63, 0x68, 0x0a, 0x4c, 0x6f, 0x6e, 0x67, 0x53, 0x74, 0x6f, 0x72, 0x61,
    0x67, 0x65, 0x0a, 0x71, 0x17, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x37,
    0x32, 0x31, 0x36, 0x71, 0x18, 0x68, 0x07, 0x4b, 0x01, 0x4e, 0x74, 0x71, 0x19, 0x51, 0x4b, 0x00,
    0x29, 0x29, 0x89, 0x68, 0x00, 0x29, 0x52, 0x71, 0x1a, 0x74, 0x71, 0x1b, 0x52, 0x71, 0x1c, 0x58,
    0x08, 0x00, 0x00, 0x00, 0x6d, 0x6f, 0x64, 0x75, 0x6c, 0x65, 0x2e, 0x64, 0x71, 0x1d, 0x68, 0x03,
    0x28, 0x28, 0x68, 0x04, 0x63, 0x74, 0x6f, 0x72, 0x63, 0x68, 0x0a, 0x44, 0x6f, 0x75, 0x62, 0x6c,
    0x65, 0x53, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x0a, 0x71, 0x1e, 0x58, 0x0a, 0x00, 0x00, 0x00,
    0x31, 0x30, 0x30, 0x32, 0x30, 0x35, 0x30, 0x30, 0x30, 0x30, 0x71, 0x1f, 0x68, 0x07, 0x4b, 0x01,
    0x4e, 0x74, 0x71, 0x20, 0x51, 0x4b, 0x00, 0x4b, 0x01, 0x85, 0x71, 0x21, 0x4b, 0x01, 0x85, 0x71,
    0x22, 0x89, 0x68, 0x00, 0x29, 0x52, 0x71, 0x23, 0x74, 0x71, 0x24, 0x52, 0x71, 0x25, 0x58, 0x06,
    0x00, 0x00, 0x00, 0x73, 0x63, 0x61, 0x6c, 0x61, 0x72, 0x71, 0x26, 0x68, 0x03, 0x28, 0x28, 0x68,
    0x04, 0x68, 0x05, 0x58, 0x0a, 0x00, 0x00, 0x00, 0x31, 0x30, 0x30, 0x32, 0x30, 0x35, 0x30, 0x31,
    0x37, 0x36, 0x71, 0x27, 0x68, 0x07, 0x4b, 0x01, 0x4e, 0x74, 0x71, 0x28, 0x51, 0x4b, 0x00, 0x29,
    0x29, 0x89, 0x68, 0x00, 0x29, 0x52, 0x71, 0x29, 0x74, 0x71, 0x2a, 0x52, 0x71, 0x2b, 0x75, 0x7d,
    0x71, 0x2c, 0x58, 0x09, 0x00, 0x00, 0x00, 0x5f, 0x6d, 0x65, 0x74, 0x61, 0x64, 0x61, 0x74, 0x61,
    0x71, 0x2d, 0x68, 0x00, 0x29, 0x52, 0x71, 0x2e, 0x58, 0x00, 0x00, 0x00, 0x00, 0x71, 0x2f, 0x7d,
    0x71, 0x30, 0x58, 0x07, 0x00, 0x00, 0x00, 0x76, 0x65, 0x72, 0x73, 0x69, 0x6f, 0x6e, 0x71, 0x31,
    0x4b, 0x01, 0x73, 0x73, 0x73, 0x62, 0x2e, 0x80, 0x02, 0x5d, 0x71, 0x00, 0x28, 0x58, 0x0a, 0x00,
    0x00, 0x00, 0x31, 0x30, 0x30, 0x32, 0x30, 0x35, 0x30, 0x30, 0x30, 0x30, 0x71, 0x01, 0x58, 0x0a,
    0x00, 0x00, 0x00, 0x31, 0x30, 0x30, 0x32, 0x30, 0x35, 0x30, 0x31, 0x37, 0x36, 0x71, 0x02, 0x58,
    0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x34, 0x39, 0x36, 0x71, 0x03, 0x58,
    0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x37, 0x32, 0x31, 0x36, 0x71, 0x04, 0x65,
    0x2e, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf8,
    0x3f, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x40, 0x0c, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xbf, 0x00, 0x00, 0xc0, 0xbe, 0x00, 0x00, 0x80,
    0xbe, 0x00, 0x00, 0x00, 0xbe, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x3e, 0x00, 0x00, 0x80,
    0x3e, 0x00, 0x00, 0xc0, 0x3e, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00, 0x20, 0x3f, 0x00, 0x00, 0x40,
    0x3f, 0x00, 0x00, 0x60, 0x3f, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x07, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00,
};
static const unsigned char fixture_transposed[367] = {
    LEGACY_HEADER,
    0x7d, 0x71, 0x00, 0x58, 0x01, 0x00, 0x00, 0x00, 0x74, 0x71, 0x01, 0x63, 0x74, 0x6f, 0x72, 0x63,
    0x68, 0x2e, 0x5f, 0x75, 0x74, 0x69, 0x6c, 0x73, 0x0a, 0x5f, 0x72, 0x65, 0x62, 0x75, 0x69, 0x6c,
    0x64, 0x5f, 0x74, 0x65, 0x6e, 0x73, 0x6f, 0x72, 0x5f, 0x76, 0x32, 0x0a, 0x71, 0x02, 0x28, 0x28,
    0x58, 0x07, 0x00, 0x00, 0x00, 0x73, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x71, 0x03, 0x63, 0x74,
    0x6f, 0x72, 0x63, 0x68, 0x0a, 0x46, 0x6c, 0x6f, 0x61, 0x74, 0x53, 0x74, 0x6f, 0x72, 0x61, 0x67,
    0x65, 0x0a, 0x71, 0x04, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x35,
    0x39, 0x32, 0x71, 0x05, 0x58, 0x03, 0x00, 0x00, 0x00, 0x63, 0x70, 0x75, 0x71, 0x06, 0x4b, 0x06,
    0x4e, 0x74, 0x71, 0x07, 0x51, 0x4b, 0x00, 0x4b, 0x03, 0x4b, 0x02, 0x86, 0x71, 0x08, 0x4b, 0x01,
    0x4b, 0x03, 0x86, 0x71, 0x09, 0x89, 0x63, 0x63, 0x6f, 0x6c, 0x6c, 0x65, 0x63, 0x74, 0x69, 0x6f,
    0x6e, 0x73, 0x0a, 0x4f, 0x72, 0x64, 0x65, 0x72, 0x65, 0x64, 0x44, 0x69, 0x63, 0x74, 0x0a, 0x71,
    0x0a, 0x29, 0x52, 0x71, 0x0b, 0x74, 0x71, 0x0c, 0x52, 0x71, 0x0d, 0x73, 0x2e, 0x80, 0x02, 0x5d,
    0x71, 0x00, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x35, 0x39, 0x32,
    0x71, 0x01, 0x61, 0x2e, 0x06, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40, 0x00, 0x00, 0x80, 0x40,
    0x00, 0x00, 0xa0, 0x40,
};
static const unsigned char fixture_two[443] = {
    LEGACY_HEADER,
    0x7d, 0x71, 0x00, 0x28, 0x58, 0x01, 0x00, 0x00, 0x00, 0x77, 0x71, 0x01, 0x63, 0x74, 0x6f, 0x72,
    0x63, 0x68, 0x2e, 0x5f, 0x75, 0x74, 0x69, 0x6c, 0x73, 0x0a, 0x5f, 0x72, 0x65, 0x62, 0x75, 0x69,
    0x6c, 0x64, 0x5f, 0x74, 0x65, 0x6e, 0x73, 0x6f, 0x72, 0x5f, 0x76, 0x32, 0x0a, 0x71, 0x02, 0x28,
    0x28, 0x58, 0x07, 0x00, 0x00, 0x00, 0x73, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x71, 0x03, 0x63,
    0x74, 0x6f, 0x72, 0x63, 0x68, 0x0a, 0x46, 0x6c, 0x6f, 0x61, 0x74, 0x53, 0x74, 0x6f, 0x72, 0x61,
    0x67, 0x65, 0x0a, 0x71, 0x04, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36,
    0x35, 0x39, 0x32, 0x71, 0x05, 0x58, 0x03, 0x00, 0x00, 0x00, 0x63, 0x70, 0x75, 0x71, 0x06, 0x4b,
    0x02, 0x4e, 0x74, 0x71, 0x07, 0x51, 0x4b, 0x00, 0x4b, 0x02, 0x85, 0x71, 0x08, 0x4b, 0x01, 0x85,
    0x71, 0x09, 0x89, 0x63, 0x63, 0x6f, 0x6c, 0x6c, 0x65, 0x63, 0x74, 0x69, 0x6f, 0x6e, 0x73, 0x0a,
    0x4f, 0x72, 0x64, 0x65, 0x72, 0x65, 0x64, 0x44, 0x69, 0x63, 0x74, 0x0a, 0x71, 0x0a, 0x29, 0x52,
    0x71, 0x0b, 0x74, 0x71, 0x0c, 0x52, 0x71, 0x0d, 0x58, 0x01, 0x00, 0x00, 0x00, 0x62, 0x71, 0x0e,
    0x68, 0x02, 0x28, 0x28, 0x68, 0x03, 0x68, 0x04, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30,
    0x32, 0x36, 0x38, 0x38, 0x34, 0x38, 0x71, 0x0f, 0x68, 0x06, 0x4b, 0x01, 0x4e, 0x74, 0x71, 0x10,
    0x51, 0x4b, 0x00, 0x4b, 0x01, 0x85, 0x71, 0x11, 0x4b, 0x01, 0x85, 0x71, 0x12, 0x89, 0x68, 0x0a,
    0x29, 0x52, 0x71, 0x13, 0x74, 0x71, 0x14, 0x52, 0x71, 0x15, 0x75, 0x2e, 0x80, 0x02, 0x5d, 0x71,
    0x00, 0x28, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x31, 0x32, 0x36, 0x35, 0x39, 0x32,
    0x71, 0x01, 0x58, 0x09, 0x00, 0x00, 0x00, 0x39, 0x34, 0x30, 0x32, 0x36, 0x38, 0x38, 0x34, 0x38,
    0x71, 0x02, 0x65, 0x2e, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3e,
    0x00, 0x00, 0x80, 0xbf, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x40,
};

/* A tensor on a storage *view*, as torch < 0.4 wrote it: persistent id ('storage', torch.FloatStorage, 'root', 'cpu',
 * 10, ('viewkey', 4, 5)), torch._utils._rebuild_tensor(storage, 1, (2, 2), (2, 1)), root data 0, 0.5, ... 4.5;
 * written by the stdlib pickler (a Pickler whose persistent_id returns that tuple, objects whose __reduce__ returns
 * the real torch._utils._rebuild_tensor) and checked with torch.load: [[2.5, 3.0], [3.5, 4.0]]. */
static const unsigned char fixture_oldview[393] = {
    LEGACY_HEADER,
    0x63, 0x63, 0x6f, 0x6c, 0x6c, 0x65, 0x63, 0x74, 0x69, 0x6f, 0x6e, 0x73, 0x0a, 0x4f, 0x72, 0x64,
    0x65, 0x72, 0x65, 0x64, 0x44, 0x69, 0x63, 0x74, 0x0a, 0x71, 0x00, 0x29, 0x52, 0x71, 0x01, 0x58,
    0x08, 0x00, 0x00, 0x00, 0x6d, 0x6f, 0x64, 0x75, 0x6c, 0x65, 0x2e, 0x76, 0x71, 0x02, 0x63, 0x74,
    0x6f, 0x72, 0x63, 0x68, 0x2e, 0x5f, 0x75, 0x74, 0x69, 0x6c, 0x73, 0x0a, 0x5f, 0x72, 0x65, 0x62,
    0x75, 0x69, 0x6c, 0x64, 0x5f, 0x74, 0x65, 0x6e, 0x73, 0x6f, 0x72, 0x0a, 0x71, 0x03, 0x28, 0x28,
    0x58, 0x07, 0x00, 0x00, 0x00, 0x73, 0x74, 0x6f, 0x72, 0x61, 0x67, 0x65, 0x71, 0x04, 0x63, 0x74,
    0x6f, 0x72, 0x63, 0x68, 0x0a, 0x46, 0x6c, 0x6f, 0x61, 0x74, 0x53, 0x74, 0x6f, 0x72, 0x61, 0x67,
    0x65, 0x0a, 0x71, 0x05, 0x58, 0x04, 0x00, 0x00, 0x00, 0x72, 0x6f, 0x6f, 0x74, 0x71, 0x06, 0x58,
    0x03, 0x00, 0x00, 0x00, 0x63, 0x70, 0x75, 0x71, 0x07, 0x4b, 0x0a, 0x58, 0x07, 0x00, 0x00, 0x00,
    0x76, 0x69, 0x65, 0x77, 0x6b, 0x65, 0x79, 0x71, 0x08, 0x4b, 0x04, 0x4b, 0x05, 0x87, 0x71, 0x09,
    0x74, 0x71, 0x0a, 0x51, 0x4b, 0x01, 0x4b, 0x02, 0x4b, 0x02, 0x86, 0x71, 0x0b, 0x4b, 0x02, 0x4b,
    0x01, 0x86, 0x71, 0x0c, 0x74, 0x71, 0x0d, 0x52, 0x71, 0x0e, 0x73, 0x2e, 0x80, 0x02, 0x5d, 0x71,
    0x00, 0x58, 0x04, 0x00, 0x00, 0x00, 0x72, 0x6f, 0x6f, 0x74, 0x71, 0x01, 0x61, 0x2e, 0x0a, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x3f, 0x00, 0x00,
    0x80, 0x3f, 0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x20, 0x40, 0x00, 0x00,
    0x40, 0x40, 0x00, 0x00, 0x60, 0x40, 0x00, 0x00, 0x80, 0x40, 0x00, 0x00, 0x90, 0x40,
};

static char tmpdir[256];

static int setup(void **state)
{
    (void)state;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/scicap-test-weights-XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

static void must_contain(const char *msg, const char *part)
{
    if (!strstr(msg, part))
        fail_msg("message \"%s\" lacks \"%s\"", msg, part);
}

/* A temporary file holding buf[0..len); its path in path. */
static void write_tmp(char *path, size_t n, const char *name, const void *buf, size_t len)
{
    snprintf(path, n, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(buf, 1, len, f), len);
    assert_int_equal(fclose(f), 0);
}

static unsigned char *read_all(const char *path, size_t *len)
{
    void *buf;
    sci_error err = {0};
    if (sci_file_read(path, (size_t)1 << 30, &buf, len, &err) < 0)
        fail_msg("%s", err.msg);
    return buf;
}

static void put_le64(unsigned char *q, uint64_t v)
{
    for (int k = 0; k < 8; k++)
        q[k] = (unsigned char)(v >> (8 * k));
}

static void put_f32(unsigned char *q, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    for (int k = 0; k < 4; k++)
        q[k] = (unsigned char)(u >> (8 * k));
}

static void expect_shape(const cnn_weights *w, const char *name, int ndim, long a, long b, long c, long d)
{
    long shape[4] = {a, b, c, d};
    sci_error err = {0};
    const cnn_tensor *t = NULL;
    if (cnn_weights_expect(w, name, ndim, shape, &t, &err) < 0)
        fail_msg("%s", err.msg);
    assert_non_null(t);
    assert_non_null(t->data);
    size_t count = 1;
    for (int k = 0; k < ndim; k++)
        count *= (size_t)shape[k];
    assert_int_equal(t->count, count);
}

static void check_value(const cnn_weights *w, const char *name, size_t i, float want)
{
    const cnn_tensor *t = cnn_weights_find(w, name);
    assert_non_null(t);
    assert_true(i < t->count);
    if (t->data[i] != want)
        fail_msg("%s[%zu] = %a, PyTorch reads %a", name, i, (double)t->data[i], (double)want);
}

/* The FFDNet layout: conv 0 (cin → f), then conv + batch norm at 3k+2, 3k+3 for k < middle, last conv (f → cout). */
static void expect_ffdnet(const cnn_weights *w, int cin, int f, int middle, int cout)
{
    char name[160];
    assert_int_equal(w->n, 1 + 5 * middle + 1);
    expect_shape(w, P "0.weight", 4, f, cin, 3, 3);
    assert_string_equal(w->t[0].name, P "0.weight");
    for (int k = 0; k < middle; k++) {
        snprintf(name, sizeof name, P "%d.weight", 3 * k + 2);
        expect_shape(w, name, 4, f, f, 3, 3);
        static const char *const bn[] = {"weight", "bias", "running_mean", "running_var"};
        for (int j = 0; j < 4; j++) {
            snprintf(name, sizeof name, P "%d.%s", 3 * k + 3, bn[j]);
            expect_shape(w, name, 1, f, 0, 0, 0);
        }
    }
    snprintf(name, sizeof name, P "%d.weight", 3 * middle + 2);
    expect_shape(w, name, 4, cout, f, 3, 3);
    assert_string_equal(w->t[w->n - 1].name, name);
    for (int k = 0; k < w->n; k++) {
        assert_int_equal(w->t[k].dtype, CNN_F32);
        assert_null(strstr(w->t[k].name, "module."));
    }
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Values from: /usr/bin/python3 -c "import torch; sd = torch.load('net_gray.pth', map_location='cpu');
 *   print(float(sd['module.intermediate_dncnn.itermediate_dncnn.' + key].flatten()[i]).hex())" */
static void test_gray(void **state)
{
    (void)state;
    char path[4096];
    TESTDATA_REQUIRE("ffdnet/net_gray.pth", path);
    cnn_weights *w = NULL;
    sci_error err = {0};
    double t0 = now_s();
    if (cnn_weights_read(path, &w, &err) < 0)
        fail_msg("%s", err.msg);
    double t1 = now_s();
    printf("net_gray.pth: %d tensors read in %.2f ms\n", w->n, 1e3 * (t1 - t0));
    assert_true(t1 - t0 < 1.0);
    assert_string_equal(w->source, path);
    expect_ffdnet(w, 5, 64, 13, 4);
    check_value(w, P "0.weight", 0, 0x1.7e161ep-7f);
    check_value(w, P "0.weight", 1, 0x1.efd8b4p-6f);
    check_value(w, P "2.weight", 1000, 0x1.5d087cp-6f);
    check_value(w, P "3.running_var", 5, 0x1.fdfc4ep-8f);
    check_value(w, P "3.bias", 63, 0x1.51c1cep-4f);
    check_value(w, P "41.weight", 2303, -0x1.804b1ap-11f);
    assert_null(cnn_weights_find(w, "module." P "0.weight"));
    assert_null(cnn_weights_find(w, P "42.weight"));

    /* expect: a wrong shape, a missing tensor */
    long bad_shape[4] = {64, 4, 3, 3};
    const cnn_tensor *t = (const cnn_tensor *)1;
    assert_int_equal(cnn_weights_expect(w, P "0.weight", 4, bad_shape, &t, &err), -EINVAL);
    assert_null(t);
    must_contain(err.msg, path);
    must_contain(err.msg, "'" P "0.weight' has shape [64, 5, 3, 3], expected [64, 4, 3, 3]");
    assert_int_equal(cnn_weights_expect(w, P "0.weight", 3, bad_shape, NULL, &err), -EINVAL);
    must_contain(err.msg, "expected [64, 4, 3]");
    assert_int_equal(cnn_weights_expect(w, "nothing.weight", 4, bad_shape, NULL, &err), -EINVAL);
    must_contain(err.msg, "no tensor 'nothing.weight'");
    cnn_weights_free(w);
}

/* Values from the same command on net_rgb.pth. */
static void test_rgb(void **state)
{
    (void)state;
    char path[4096];
    TESTDATA_REQUIRE("ffdnet/net_rgb.pth", path);
    cnn_weights *w = NULL;
    sci_error err = {0};
    if (cnn_weights_read(path, &w, &err) < 0)
        fail_msg("%s", err.msg);
    expect_ffdnet(w, 15, 96, 10, 12); /* 12 conv layers */
    check_value(w, P "0.weight", 0, -0x1.04ce26p-3f);
    check_value(w, P "0.weight", 1, -0x1.139a38p-2f);
    check_value(w, P "2.weight", 1000, -0x1.aa451ep-4f);
    check_value(w, P "3.running_var", 5, 0x1.12d4e2p-7f);
    check_value(w, P "3.bias", 63, 0x1.a5d7d6p-1f);
    check_value(w, P "32.weight", 10367, -0x1.21ff6ap-11f);
    cnn_weights_free(w);
}

/* Shared storage, offsets, 0-d tensors, Long and Double storages, BUILD with _metadata, both key forms. */
static void test_views_and_dtypes(void **state)
{
    (void)state;
    cnn_weights *w = NULL;
    sci_error err = {0};
    if (cnn_weights_parse(fixture_views, sizeof fixture_views, "views.pth", &w, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(w->n, 5);
    assert_string_equal(w->source, "views.pth");
    static const char *const names[] = {"conv.weight", "view", "bn.num_batches_tracked", "d", "scalar"};
    for (int k = 0; k < 5; k++)
        assert_string_equal(w->t[k].name, names[k]);
    const cnn_tensor *c = &w->t[0], *v = &w->t[1], *n = &w->t[2], *d = &w->t[3], *s = &w->t[4];
    assert_int_equal(c->dtype, CNN_F32);
    assert_int_equal(c->ndim, 4);
    assert_int_equal(c->shape[0], 2);
    assert_int_equal(c->shape[1], 1);
    assert_int_equal(c->shape[3], 2);
    assert_int_equal(c->count, 8);
    for (int k = 0; k < 8; k++)
        assert_true(c->data[k] == (float)k / 8 - 0.5f);
    assert_int_equal(v->ndim, 1);
    assert_int_equal(v->count, 3);
    assert_ptr_equal(v->data, c->data + 8); /* one copy of the storage */
    for (int k = 0; k < 3; k++)
        assert_true(v->data[k] == (float)(k + 8) / 8 - 0.5f);
    assert_int_equal(n->dtype, CNN_I64);
    assert_int_equal(n->ndim, 0);
    assert_int_equal(n->count, 1);
    assert_null(n->data);
    assert_int_equal(d->dtype, CNN_OTHER);
    assert_null(d->data);
    assert_int_equal(s->dtype, CNN_F32);
    assert_int_equal(s->ndim, 0);
    assert_int_equal(s->count, 1);
    assert_true(s->data[0] == 2.25f);

    long one[1] = {1};
    assert_int_equal(cnn_weights_expect(w, "d", 1, one, NULL, &err), -EINVAL);
    must_contain(err.msg, "views.pth: tensor 'd' [1] is not float32");
    assert_int_equal(cnn_weights_expect(w, "scalar", 0, one, NULL, &err), 0);
    assert_int_equal(cnn_weights_expect(w, "scalar", 1, one, NULL, &err), -EINVAL);
    must_contain(err.msg, "has shape [], expected [1]");
    cnn_weights_free(w);
    cnn_weights_free(NULL);

    if (cnn_weights_parse(fixture_oldview, sizeof fixture_oldview, "oldview.pth", &w, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(w->n, 1);
    assert_string_equal(w->t[0].name, "v");
    assert_int_equal(w->t[0].count, 4);
    for (int k = 0; k < 4; k++)
        assert_true(w->t[0].data[k] == 2.5f + 0.5f * (float)k);
    cnn_weights_free(w);

    if (cnn_weights_parse(fixture_two, sizeof fixture_two, "two.pth", &w, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(w->n, 2);
    assert_true(w->t[0].data[1] == -1.0f && w->t[1].data[0] == 3.0f);
    cnn_weights_free(w);
}

static void expect_refused(const void *buf, size_t len, const char *name, int code, const char *part)
{
    cnn_weights *w = (cnn_weights *)1;
    sci_error err = {0};
    int rc = cnn_weights_parse(buf, len, name, &w, &err);
    if (rc != code)
        fail_msg("%s: returned %d, expected %d (%s)", name, rc, code, err.msg);
    assert_null(w);
    must_contain(err.msg, name);
    must_contain(err.msg, part);
    printf("  refused as expected: %s\n", err.msg);
}

static void test_small_faults(void **state)
{
    (void)state;
    expect_refused(fixture_transposed, sizeof fixture_transposed, "transposed.pth", SCI_EFORMAT,
                   "tensor 't' is not contiguous (dimension 1: stride 3, expected 1)");

    /* storage 'b' declares 200 elements, in its pickle and its record: more than the file holds */
    unsigned char two[sizeof fixture_two];
    memcpy(two, fixture_two, sizeof two);
    assert_int_equal(two[342], 1);
    two[342] = 200;
    put_le64(two + 431, 200);
    expect_refused(two, sizeof two, "two.pth", SCI_EFORMAT,
                   "truncated: storage '940268848' needs 800 bytes at offset 439, file has 443");
    /* only the record's count changed: they disagree */
    memcpy(two, fixture_two, sizeof two);
    put_le64(two + 431, (uint64_t)1 << 40);
    expect_refused(two, sizeof two, "two.pth", SCI_EFORMAT,
                   "storage '940268848': the record at offset 431 holds 1099511627776 elements, the pickle declared 1");
    /* the view pointing past its storage: 'b''s numel 1 → 0 in the pickle and the record */
    memcpy(two, fixture_two, sizeof two);
    two[342] = 0;
    put_le64(two + 431, 0);
    expect_refused(two, sizeof two - 4, "two.pth", SCI_EFORMAT, "tensor 'b': elements [0, 0 + 1) outside its storage");
    /* an Inf in 'w' */
    memcpy(two, fixture_two, sizeof two);
    put_f32(two + 423 + 4, -INFINITY);
    expect_refused(two, sizeof two, "two.pth", SCI_ENONFINITE, "tensor 'w' element 1 (of 2) is -Inf");
    /* trailing bytes */
    unsigned char longer[sizeof fixture_two + 3] = {0};
    memcpy(longer, fixture_two, sizeof fixture_two);
    expect_refused(longer, sizeof longer, "two.pth", SCI_EFORMAT, "3 unexpected bytes after the last storage");
    /* the view (4, 5) moved to (6, 5): past its root storage of 10 */
    unsigned char oldview[sizeof fixture_oldview];
    memcpy(oldview, fixture_oldview, sizeof oldview);
    unsigned char *at = memmem(oldview, sizeof oldview, "viewkey", 7);
    assert_non_null(at);
    assert_true(at[9] == 'K' && at[10] == 4); /* BINPUT n, BININT1 4 */
    at[10] = 6;
    expect_refused(oldview, sizeof oldview, "oldview.pth", SCI_EFORMAT,
                   "tensor 'module.v': storage view [6, 6 + 5) outside storage 'root' of 10");
    /* every proper prefix is refused, none crashes */
    for (size_t n = 0; n < sizeof fixture_views; n++) {
        cnn_weights *w = NULL;
        sci_error err = {0};
        assert_true(cnn_weights_parse(fixture_views, n, "views.pth", &w, &err) < 0);
        assert_null(w);
        must_contain(err.msg, "views.pth: ");
    }
    expect_refused("PK\3\4rest", 8, "zip.pth", SCI_EFORMAT, "_use_new_zipfile_serialization=False");
}

static void test_missing_and_empty(void **state)
{
    (void)state;
    char path[512];
    snprintf(path, sizeof path, "%s/does-not-exist.pth", tmpdir);
    cnn_weights *w = (cnn_weights *)1;
    sci_error err = {0};
    assert_int_equal(cnn_weights_read(path, &w, &err), -ENOENT);
    assert_null(w);
    must_contain(err.msg, path);
    must_contain(err.msg, strerror(ENOENT));

    write_tmp(path, sizeof path, "empty.pth", "", 0);
    assert_int_equal(cnn_weights_read(path, &w, &err), SCI_EFORMAT);
    assert_null(w);
    must_contain(err.msg, path);
    must_contain(err.msg, "empty file");
}

/* Damaged copies of net_gray.pth. Its layout (pickletools.dis and the key list): the state-dict pickle starts at
 * 137 with GLOBAL 'collections OrderedDict' at 139; the data records start at 11354 with storage '94211066295984'
 * (64 floats of module.intermediate_dncnn.itermediate_dncnn.30.weight at 11362); the last record, storage
 * '94212659224832' (36864 floats of ...14.weight), has its data at 1815410 and ends the file at 1962866. */
static void test_gray_damaged(void **state)
{
    (void)state;
    char src[4096], path[512];
    TESTDATA_REQUIRE("ffdnet/net_gray.pth", src);
    size_t len;
    unsigned char *buf = read_all(src, &len);
    assert_int_equal(len, 1962866);
    cnn_weights *w = NULL;
    sci_error err = {0};

    /* truncated: 10 %, 50 %, one byte short, inside the pickles, inside a record's count */
    const size_t cuts[] = {len / 10, len / 2, len - 1, 5000, 11354 + 4};
    for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
        char name[64], has[64];
        snprintf(name, sizeof name, "cut%zu.pth", cuts[k]);
        write_tmp(path, sizeof path, name, buf, cuts[k]);
        w = (cnn_weights *)1;
        assert_int_equal(cnn_weights_read(path, &w, &err), SCI_EFORMAT);
        assert_null(w);
        must_contain(err.msg, path);
        must_contain(err.msg, "truncated");
        if (cuts[k] > 11354) {
            snprintf(has, sizeof has, ", file has %zu", cuts[k]);
            must_contain(err.msg, has);
            must_contain(err.msg, "storage '");
        }
        printf("  %s\n", err.msg);
    }
    write_tmp(path, sizeof path, "short1.pth", buf, len - 1);
    assert_int_equal(cnn_weights_read(path, &w, &err), SCI_EFORMAT);
    char want[512];
    snprintf(want, sizeof want,
             "%s: truncated: storage '94212659224832' needs 147456 bytes at offset 1815410, file has 1962865", path);
    assert_string_equal(err.msg, want);

    /* a corrupted byte in the pickle: GLOBAL's opcode */
    unsigned char *bad = malloc(len);
    assert_non_null(bad);
    memcpy(bad, buf, len);
    bad[139] = 0xff;
    expect_refused(bad, len, "gray-opcode.pth", SCI_EFORMAT, "pickle 4 (state dict): offset 139: unsupported pickle "
                                                             "opcode 0xff");
    /* ... and a size in the first tensor's shape (64 → 65): beyond its storage */
    memcpy(bad, buf, len);
    assert_int_equal(bad[346], 64);
    bad[346] = 65;
    expect_refused(bad, len, "gray-size.pth", SCI_EFORMAT,
                   "tensor 'module." P "0.weight': elements [0, 0 + 2925) outside its storage '94212644107616' of "
                   "2880");
    /* a record count larger than the file */
    memcpy(bad, buf, len);
    put_le64(bad + 11354, (uint64_t)1 << 40);
    expect_refused(bad, len, "gray-count.pth", SCI_EFORMAT,
                   "storage '94211066295984': the record at offset 11354 holds 1099511627776 elements, the pickle "
                   "declared 64");
    /* a NaN in a weight, through a file */
    memcpy(bad, buf, len);
    put_f32(bad + 11362 + 4 * 5, NAN);
    write_tmp(path, sizeof path, "nan.pth", bad, len);
    w = (cnn_weights *)1;
    assert_int_equal(cnn_weights_read(path, &w, &err), SCI_ENONFINITE);
    assert_null(w);
    must_contain(err.msg, path);
    must_contain(err.msg, "tensor 'module." P "30.weight' element 5 (of 64) is NaN");
    free(bad);
    free(buf);
}

/* --- the pickle machine on its own --- */

/* One pickle of `len` bytes: its result, or NULL with the message in err. */
static const cnn_pickle_obj *pk_run(cnn_pickle *pk, const char *bytes, size_t len, sci_error *err)
{
    const cnn_pickle_obj *o = NULL;
    size_t pos = 0;
    int rc = cnn_pickle_load(pk, (const unsigned char *)bytes, len, &pos, &o, err);
    if (rc == 0)
        assert_int_equal(pos, len);
    else
        assert_int_equal(pos, 0);
    return rc == 0 ? o : NULL;
}

static void pk_refused(const char *bytes, size_t len, const cnn_pickle_limits *lim, const char *part)
{
    cnn_pickle *pk;
    assert_int_equal(cnn_pickle_new(lim, &pk), 0);
    sci_error err = {0};
    if (pk_run(pk, bytes, len, &err))
        fail_msg("accepted a pickle that should fail with \"%s\"", part);
    assert_int_equal(err.code, SCI_EFORMAT);
    must_contain(err.msg, part);
    cnn_pickle_free(pk);
}

#define PK(s) s, sizeof s - 1

/* Protocol 4 as Python 3 writes it (FRAME, MEMOIZE, SHORT_BINUNICODE, SHORT_BINBYTES, STACK_GLOBAL), hand-made
 * sequences for the opcodes torch does not use, cycles, and the limits. */
static void test_pickle_machine(void **state)
{
    (void)state;
    cnn_pickle *pk;
    sci_error err = {0};
    assert_int_equal(cnn_pickle_new(NULL, &pk), 0);

    /* pickle.dumps([1, -2, 3.5, 'é', b'xy', (None, True, False), {'a': 1}, 2**70, -129, (), (1,), (1, 2),
     *               (1, 2, 3)], protocol=4) */
    const cnn_pickle_obj *o = pk_run(pk, PK("\x80\x04\x95\x50\x00\x00\x00\x00\x00\x00\x00\x5d\x94\x28\x4b\x01\x4a\xfe"
        "\xff\xff\xff\x47\x40\x0c\x00\x00\x00\x00\x00\x00\x8c\x02\xc3\xa9\x94\x43\x02\x78\x79\x94\x4e\x88\x89\x87"
        "\x94\x7d\x94\x8c\x01\x61\x94\x4b\x01\x73\x8a\x09\x00\x00\x00\x00\x00\x00\x00\x00\x40\x4a\x7f\xff\xff\xff"
        "\x29\x4b\x01\x85\x94\x4b\x01\x4b\x02\x86\x94\x4b\x01\x4b\x02\x4b\x03\x87\x94\x65\x2e"), &err);
    if (!o)
        fail_msg("%s", err.msg);
    assert_int_equal(o->kind, CNN_PICKLE_LIST);
    assert_int_equal(o->n, 13);
    cnn_pickle_obj *const *it = o->items;
    assert_true(it[0]->kind == CNN_PICKLE_INT && it[0]->i == 1);
    assert_true(it[1]->kind == CNN_PICKLE_INT && it[1]->i == -2);
    assert_true(it[2]->kind == CNN_PICKLE_FLOAT && it[2]->f == 3.5);
    assert_true(cnn_pickle_is_str(it[3], "\xc3\xa9"));
    assert_true(it[4]->kind == CNN_PICKLE_BYTES && it[4]->len == 2 && memcmp(it[4]->s, "xy", 2) == 0);
    assert_true(it[5]->kind == CNN_PICKLE_TUPLE && it[5]->n == 3 && it[5]->items[0]->kind == CNN_PICKLE_NONE);
    assert_true(it[5]->items[1]->kind == CNN_PICKLE_BOOL && it[5]->items[1]->i == 1 && it[5]->items[2]->i == 0);
    const cnn_pickle_obj *a = cnn_pickle_dict_get(it[6], "a");
    assert_true(a && a->kind == CNN_PICKLE_INT && a->i == 1);
    assert_null(cnn_pickle_dict_get(it[6], "b"));
    assert_true(it[7]->kind == CNN_PICKLE_BIGINT && it[7]->len == 9 && (unsigned char)it[7]->s[8] == 0x40);
    assert_true(it[8]->kind == CNN_PICKLE_INT && it[8]->i == -129);
    for (size_t k = 0; k < 4; k++)
        assert_true(it[9 + k]->kind == CNN_PICKLE_TUPLE && it[9 + k]->n == k);

    /* pickle.dumps(collections.OrderedDict(a=1), protocol=4): STACK_GLOBAL, REDUCE, SETITEM on the call */
    o = pk_run(pk, PK("\x80\x04\x95\x29\x00\x00\x00\x00\x00\x00\x00\x8c\x0b\x63\x6f\x6c\x6c\x65\x63\x74\x69\x6f\x6e\x73"
                      "\x94\x8c\x0b\x4f\x72\x64\x65\x72\x65\x64\x44\x69\x63\x74\x94\x93\x94\x29\x52\x94\x8c\x01\x61\x94"
                      "\x4b\x01\x73\x2e"), &err);
    if (!o)
        fail_msg("%s", err.msg);
    assert_int_equal(o->kind, CNN_PICKLE_CALL);
    assert_true(cnn_pickle_is_global(o->fn, "collections", "OrderedDict"));
    assert_true(cnn_pickle_dict_get(o, "a")->i == 1);

    /* LONG1 negative; DUP, POP, POP_MARK; LIST, DICT, TUPLE2 */
    o = pk_run(pk, PK("\x8a\x02\x7f\xff."), &err);
    assert_true(o && o->kind == CNN_PICKLE_INT && o->i == -129);
    o = pk_run(pk, PK("K\x01" "20" "(K\x02K\x03" "1."), &err);
    assert_true(o && o->kind == CNN_PICKLE_INT && o->i == 1);
    o = pk_run(pk, PK("(K\x01K\x02l(U\x01" "aK\x05" "d\x86."), &err);
    assert_true(o && o->kind == CNN_PICKLE_TUPLE && o->n == 2);
    assert_true(o->items[0]->kind == CNN_PICKLE_LIST && o->items[0]->n == 2 && o->items[0]->items[1]->i == 2);
    assert_true(cnn_pickle_dict_get(o->items[1], "a")->i == 5);
    /* NEWOBJ, BUILD, BINPERSID, BINBYTES */
    o = pk_run(pk, PK("cm\nC\n)\x81}U\x01kB\x01\x00\x00\x00zsbQ."), &err);
    if (!o)
        fail_msg("%s", err.msg);
    assert_true(o->kind == CNN_PICKLE_PERSID && o->args->kind == CNN_PICKLE_CALL && o->args->newobj);
    assert_true(cnn_pickle_is_global(o->args->fn, "m", "C"));
    assert_true(cnn_pickle_dict_get(o->args->state, "k")->kind == CNN_PICKLE_BYTES);
    /* a list that holds itself (through the memo): read, and freed without walking it */
    o = pk_run(pk, PK("]q\x00h\x00" "a."), &err);
    assert_true(o && o->kind == CNN_PICKLE_LIST && o->n == 1 && o->items[0] == o);
    /* the memo does not survive from one pickle to the next */
    assert_null(pk_run(pk, PK("h\x00."), &err));
    must_contain(err.msg, "offset 0: opcode 0x68: memo index 0 was never set");
    cnn_pickle_free(pk);

    /* refused: unknown opcodes (named by byte and offset), malformed sequences, truncation, limits */
    pk_refused(PK("\x80\x02I01\n."), NULL, "offset 2: unsupported pickle opcode 0x49 ('I')");
    pk_refused(PK("\x80\x02\x8a\x01\x05\xff."), NULL, "offset 5: unsupported pickle opcode 0xff");
    pk_refused(PK("K\x01K\x02."), NULL, "STOP with 2 objects on the stack, not 1");
    pk_refused(PK("(K\x01."), NULL, "STOP with 1 MARK(s) open");
    pk_refused(PK("K\x01"), NULL, "truncated: the pickle ends without STOP");
    pk_refused(PK("M\x01"), NULL, "offset 0: opcode 0x4d: truncated: needs 2 bytes, 1 left");
    pk_refused(PK("X\x00\x00\x01\x00" "abc."), NULL, "truncated: needs 65536 bytes, 4 left");
    pk_refused(PK("X\xff\xff\xff\x00."), NULL, "string of 16777215 bytes (limit 1048576)");
    pk_refused(PK("K\x01r\xff\xff\xff\x7f."), NULL, "memo index 2147483647 (limit 131072)");
    pk_refused(PK("t."), NULL, "no MARK to close");
    pk_refused(PK("(K\x01" "0" "0" "0."), NULL, "stack underflow");
    pk_refused(PK("K\x01(K\x02" "e."), NULL, "APPENDS on a int");
    pk_refused(PK("K\x01)R."), NULL, "calls a int, not a global");
    pk_refused(PK("}}b."), NULL, "BUILD on a dict");
    pk_refused(PK("cmod\n"), NULL, "GLOBAL without its newline");
    pk_refused(PK("\x80\x06."), NULL, "pickle protocol 6");
    char marks[1100];
    memset(marks, '(', sizeof marks);
    pk_refused(marks, sizeof marks, NULL, "more than 1024 open MARKs (limit)");
    cnn_pickle_limits lim;
    cnn_pickle_limits_default(&lim);
    lim.stack = 4;
    pk_refused(PK("NNNNN"), &lim, "stack deeper than 4 (limit)");
    cnn_pickle_limits_default(&lim);
    lim.objects = 3;
    pk_refused(PK("(NNNN"), &lim, "more than 3 objects (limit)");
    cnn_pickle_limits_default(&lim);
    lim.entries = 6;
    pk_refused(PK("]q\x00h\x00" "ah\x00" "ah\x00" "ah\x00" "ah\x00" "ah\x00" "ah\x00" "a0."), &lim,
               "more than 6 container entries (limit)");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_gray),         cmocka_unit_test(test_rgb),
        cmocka_unit_test(test_views_and_dtypes), cmocka_unit_test(test_small_faults),
        cmocka_unit_test(test_missing_and_empty), cmocka_unit_test(test_gray_damaged),
        cmocka_unit_test(test_pickle_machine),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
