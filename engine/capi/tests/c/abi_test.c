/* The C ABI from C: create, load, render and free N times (argv[1], default 1), checking every
 * result, the frame's values and the validation count; then the misuse cases a C caller can
 * make. Built with -Wall -Wextra -Werror (and, by tools/examples/sanitize.sh, under ASan + UBSan
 * and valgrind). Exit 0 when every check holds; each failed check prints one line. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lensmap.h"

static int failures = 0;

#define CHECK(condition, what)                                                      \
    do {                                                                            \
        if (!(condition)) {                                                         \
            fprintf(stderr, "FAILED %s:%d: %s (last error: %s)\n", __FILE__, __LINE__, \
                    what, lensmap_last_error());                                    \
            failures++;                                                             \
        }                                                                           \
    } while (0)

#define WIDTH 40
#define HEIGHT 30

static LensmapFrameOptions frame_options(uint32_t format) {
    LensmapFrameOptions options;
    memset(&options, 0, sizeof options);
    options.struct_size = sizeof options;
    /* glass-sphere's scene camera. */
    options.position[0] = 0.0f;
    options.position[1] = 2.5f;
    options.position[2] = 5.0f;
    options.look_at[0] = 0.0f;
    options.look_at[1] = 1.0f;
    options.look_at[2] = 0.0f;
    options.up[1] = 1.0f;
    options.vfov_degrees = 40.0f;
    options.width = WIDTH;
    options.height = HEIGHT;
    options.supersampling = 1;
    options.t = 3.0f;
    options.variant = LENSMAP_VARIANT_SINGLE_PASS;
    options.format = format;
    return options;
}

static LensmapSceneOptions scene_options(const char *scene) {
    LensmapSceneOptions options;
    memset(&options, 0, sizeof options);
    options.struct_size = sizeof options;
    options.scene = scene;
    options.em_size = 8;
    return options;
}

/* One create, load, render, free cycle. */
static void cycle(int validation) {
    LensmapContextOptions context_options;
    memset(&context_options, 0, sizeof context_options);
    context_options.struct_size = sizeof context_options;
    context_options.validation = (uint32_t)validation;
    LensmapContext *context = NULL;
    CHECK(lensmap_context_new(&context_options, &context) == LENSMAP_RESULT_OK, "context_new");
    LensmapSceneOptions options = scene_options("glass-sphere");
    LensmapScene *scene = NULL;
    CHECK(lensmap_scene_load(&options, &scene) == LENSMAP_RESULT_OK, "scene_load");
    if (context == NULL || scene == NULL) {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
        return;
    }
    size_t floats = 4 * WIDTH * HEIGHT;
    float *rgba = malloc(floats * sizeof *rgba);
    CHECK(rgba != NULL, "malloc");
    LensmapFrameStats stats;
    memset(&stats, 0, sizeof stats);
    stats.struct_size = sizeof stats;
    LensmapFrameOptions frame = frame_options(LENSMAP_FORMAT_RGBA32F);
    CHECK(lensmap_render_to_memory(context, scene, &frame, rgba, floats, &stats) ==
              LENSMAP_RESULT_OK,
          "render_to_memory");
    double sum = 0.0;
    for (size_t i = 0; i < floats; i++) {
        CHECK(isfinite(rgba[i]), "finite pixel");
        sum += rgba[i];
    }
    CHECK(sum > 0.0, "a lit image");
    CHECK(stats.passes >= 2 && stats.total_ms > 0.0, "stats filled");
    uint64_t messages = 1;
    CHECK(lensmap_context_validation_messages(context, &messages) == LENSMAP_RESULT_OK,
          "validation_messages");
    CHECK(messages == 0, "no validation messages");
    free(rgba);
    CHECK(lensmap_scene_free(scene) == LENSMAP_RESULT_OK, "scene_free");
    CHECK(lensmap_context_free(context) == LENSMAP_RESULT_OK, "context_free");
}

static void misuse(void) {
    CHECK(lensmap_context_free(NULL) == LENSMAP_RESULT_OK, "free(NULL) is a no-op");
    CHECK(lensmap_scene_free(NULL) == LENSMAP_RESULT_OK, "free(NULL) is a no-op");
    CHECK(lensmap_context_new(NULL, NULL) == LENSMAP_RESULT_NULL_ARGUMENT, "NULL out");

    LensmapSceneOptions options = scene_options("glass-sphere");
    options.struct_size = 3;
    LensmapScene *scene = (LensmapScene *)&options; /* a sentinel that must stay untouched */
    CHECK(lensmap_scene_load(&options, &scene) == LENSMAP_RESULT_STRUCT_SIZE, "struct size");
    CHECK(scene == (LensmapScene *)&options, "out-pointer untouched");
    CHECK(strstr(lensmap_last_error(), "struct_size") != NULL, "message names struct_size");

    options = scene_options("no-such-scene");
    CHECK(lensmap_scene_load(&options, &scene) == LENSMAP_RESULT_SCENE, "unknown scene");
    CHECK(strstr(lensmap_last_error(), "no-such-scene") != NULL, "message names the scene");

    LensmapContext *context = NULL;
    CHECK(lensmap_context_new(NULL, &context) == LENSMAP_RESULT_OK, "default context");
    options = scene_options("glass-sphere");
    CHECK(lensmap_scene_load(&options, &scene) == LENSMAP_RESULT_OK, "scene");
    float small[8];
    LensmapFrameOptions frame = frame_options(LENSMAP_FORMAT_RGBA8);
    CHECK(lensmap_render_to_memory(context, scene, &frame, small, 8, NULL) ==
              LENSMAP_RESULT_BUFFER_TOO_SMALL,
          "buffer too small");
    frame = frame_options(42);
    float *rgba = malloc(4 * WIDTH * HEIGHT * sizeof *rgba);
    CHECK(lensmap_render_to_memory(context, scene, &frame, rgba, 4 * WIDTH * HEIGHT, NULL) ==
              LENSMAP_RESULT_UNSUPPORTED_FORMAT,
          "unsupported format");
    frame = frame_options(LENSMAP_FORMAT_RGBA8);
    frame.width = 0;
    CHECK(lensmap_render_to_memory(context, scene, &frame, rgba, 4 * WIDTH * HEIGHT, NULL) ==
              LENSMAP_RESULT_INVALID_ARGUMENT,
          "zero-size image");
    free(rgba);

    size_t length = 0;
    LensmapPlanOptions plan = {sizeof plan, 3, 2, 2, LENSMAP_VARIANT_MULTIPASS, LENSMAP_FORMAT_RGBA8,
                               LENSMAP_BLEND_FRONT_TO_BACK};
    CHECK(lensmap_plan_text(&plan, NULL, 0, &length) == LENSMAP_RESULT_OK && length > 0,
          "plan size query");
    char *text = malloc(length + 1);
    CHECK(lensmap_plan_text(&plan, text, length + 1, &length) == LENSMAP_RESULT_OK, "plan");
    CHECK(text != NULL && strstr(text, "alpha-clear") != NULL, "plan text");
    free(text);
    plan.blend = LENSMAP_BLEND_GROUP_TARGETS;
    CHECK(lensmap_plan_text(&plan, NULL, 0, &length) == LENSMAP_RESULT_OK && length > 0,
          "group-targets plan size query");
    text = malloc(length + 1);
    CHECK(lensmap_plan_text(&plan, text, length + 1, &length) == LENSMAP_RESULT_OK,
          "group-targets plan");
    CHECK(text != NULL && strstr(text, "group-sum") != NULL, "group-targets plan text");
    free(text);
    /* Three viewpoint samples (ABI 4): six groups, the last viewpoint's reflection last. */
    plan.blend = LENSMAP_BLEND_FRONT_TO_BACK;
    plan.viewpoints = 3;
    CHECK(lensmap_plan_text(&plan, NULL, 0, &length) == LENSMAP_RESULT_OK && length > 0,
          "three-viewpoint plan size query");
    text = malloc(length + 1);
    CHECK(lensmap_plan_text(&plan, text, length + 1, &length) == LENSMAP_RESULT_OK,
          "three-viewpoint plan");
    CHECK(text != NULL && strstr(text, "lens/v2/R/alpha-clear") != NULL,
          "three-viewpoint plan text");
    free(text);
    plan.viewpoints = 4;
    CHECK(lensmap_plan_text(&plan, NULL, 0, &length) == LENSMAP_RESULT_INVALID_ARGUMENT,
          "four viewpoints refused");

    CHECK(lensmap_scene_free(scene) == LENSMAP_RESULT_OK, "scene_free");
    CHECK(lensmap_scene_free(scene) == LENSMAP_RESULT_INVALID_HANDLE, "double free detected");
    CHECK(lensmap_context_free(context) == LENSMAP_RESULT_OK, "context_free");
    CHECK(lensmap_context_free(context) == LENSMAP_RESULT_INVALID_HANDLE,
          "double free detected");
}

int main(int argc, char **argv) {
    int cycles = argc > 1 ? atoi(argv[1]) : 1;
    int validation = getenv("LENSMAP_VALIDATION") != NULL;
    CHECK(lensmap_abi_version() == LENSMAP_ABI_VERSION, "the header matches the library");
    for (int i = 0; i < cycles && failures == 0; i++) {
        cycle(validation);
    }
    misuse();
    if (failures == 0) {
        printf("ok: %d cycle(s) and the misuse cases\n", cycles);
    }
    return failures == 0 ? 0 : 1;
}
