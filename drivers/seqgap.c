#include "drivers/seqgap.h"

#include <string.h>

void seqgap_reset(seqgap *g) { memset(g, 0, sizeof *g); }

uint32_t seqgap_between(uint32_t a, uint32_t b)
{
    uint32_t step = b - a; /* unsigned: wraps by definition */
    if (step == 0 || step >= 0x80000000u)
        return 0;
    return step - 1;
}

uint32_t seqgap_push(seqgap *g, uint32_t seq)
{
    g->frames++;
    if (!g->primed) {
        g->primed = 1;
        g->last = seq;
        return 0;
    }
    uint32_t step = seq - g->last;
    uint32_t lost = 0;
    if (step == 0)
        g->repeats++;
    else if (step >= 0x80000000u)
        g->resets++;
    else if (step > 1) {
        lost = step - 1;
        g->lost += lost;
        g->gaps++;
    }
    g->last = seq;
    return lost;
}
