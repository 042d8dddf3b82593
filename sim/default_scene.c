#include "sim/default_scene.h"

static const char scene_json[] =
    "{\n"
    "  \"version\": 1,\n"
    "  \"kind\": \"video2d\",\n"
    "  \"name\": \"default\",\n"
    "  \"description\": \"moving textured disc and pentagon over a textured background\",\n"
    "  \"width\": 256, \"height\": 256, \"frames\": 8, \"snapshots\": 1, \"bit_depth\": 12, \"seed\": 1,\n"
    "  \"supersample\": 2,\n"
    "  \"layers\": [\n"
    "    {\"texture\": {\"type\": \"noise\", \"cell\": 48, \"octaves\": 4, \"values\": [0.15, 0.75]}},\n"
    "    {\"shape\": \"polygon\", \"sides\": 5, \"size\": [90, 90], \"position\": [170, 90],\n"
    "     \"velocity\": [-3, 2], \"angle_rad\": 0.2, \"spin_rad\": 0.05,\n"
    "     \"texture\": {\"type\": \"checkerboard\", \"cell\": 10, \"values\": [0.1, 0.95]}},\n"
    "    {\"shape\": \"disc\", \"size\": [80, 80], \"position\": [70, 160], \"velocity\": [4, -1.5],\n"
    "     \"texture\": {\"type\": \"radial\", \"center\": [40, 40], \"length\": 40, \"values\": [1.0, 0.35]}}\n"
    "  ],\n"
    "  \"masks\": {\"type\": \"random\", \"density\": 0.5}\n"
    "}\n";

const char *sim_default_scene_json(void) { return scene_json; }

int sim_default_scene_load(sim_scene **out, sci_error *err)
{
    return sim_scene_load_string(out, "default-scene", scene_json, NULL, err);
}
