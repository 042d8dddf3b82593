/* libFuzzer target: the DLPC900 report parser and the emulator behind it.
 *
 * The input is cut into reports of up to 64 bytes; each is fed to the emulator (message reassembly, every
 * command handler, image load and decode) and to the host-side reply parser; pending replies are drained
 * after each report and parsed too. The emulator's DMD is 64×32 so image decodes stay cheap. Byte 0 of each
 * 65-byte record sets the report length (0…64) so short reports are exercised as well. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_proto.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    dlpc900_emu *emu;
    sci_error err = {0};
    if (dlpc900_emu_new(&emu, &(dlpc900_emu_config){.width = 64, .height = 32}, &err) < 0)
        return 0;
    size_t pos = 0;
    while (pos < size) {
        size_t len = data[pos] % 65;
        pos++;
        if (len > size - pos)
            len = size - pos;
        dlpc900_reply r;
        dlpc900_reply_parse(data + pos, len, &r, &err);
        dlpc900_emu_write(emu, data + pos, len);
        pos += len;
        uint8_t rep[DLPC900_REPORT_SIZE];
        int n;
        while ((n = dlpc900_emu_read(emu, rep)) > 0)
            if (dlpc900_reply_parse(rep, (size_t)n, &r, &err) == 0 && r.len > DLPC900_REPLY_DATA_MAX)
                __builtin_trap();
    }
    uint8_t *mask = malloc(64 * 32);
    for (int i = 0; i < 4; i++)
        dlpc900_emu_mask(emu, i, mask);
    free(mask);
    dlpc900_emu_displayed_at(emu, 123456789, NULL);
    dlpc900_emu_free(emu);
    return 0;
}
