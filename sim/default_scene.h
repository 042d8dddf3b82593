/* sim/default_scene.h — the embedded default scene: what the daemon's simulated bench and `make demo` show when
 * no scene file is given. A video2d scene, 256×256, 8 frames per snapshot, one snapshot: a noise-textured disc
 * and a checkered pentagon moving (and turning) over a smooth-noise background, random masks of density 0.5,
 * no effects. */
#ifndef SCICAP_SIM_DEFAULT_SCENE_H
#define SCICAP_SIM_DEFAULT_SCENE_H

#include "sim/scene.h"

/* The scene's JSON text (static storage, NUL-terminated). */
const char *sim_default_scene_json(void);
/* Load it (name "default-scene"). */
int sim_default_scene_load(sim_scene **out, sci_error *err);

#endif
