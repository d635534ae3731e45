/* The C API's error paths, without a Vulkan device: NULL and invalid
 * arguments return a status and a message, never crash. Run by
 * capi/tests/c_example.rs. */
#include <stdio.h>
#include <string.h>

#include "mcdenoise.h"

static int failures = 0;

static void expect(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "FAILED: %s (last error: '%s')\n", what, mcd_last_error());
        failures++;
    }
}

int main(void)
{
    McdContext *ctx = NULL;
    McdDenoiser *dn = NULL;
    McdRecording *rec = NULL;
    McdOutputs out;
    McdAccumLayout empty = {0};
    McdAccumLayout layout = {.width = 16, .height = 8};
    McdVulkanDevice nulls = {0};
    McdDenoiserDesc desc = {.layout = layout, .method = 42};

    expect(mcd_api_version() == MCDENOISE_API_VERSION, "version");
    expect(mcd_context_create(NULL, &ctx) == MCD_STATUS_INVALID_ARGUMENT, "context from NULL");
    expect(strstr(mcd_last_error(), "NULL") != NULL, "message names the NULL");
    expect(mcd_context_create(&nulls, &ctx) == MCD_STATUS_INVALID_ARGUMENT,
           "context from null handles");
    expect(ctx == NULL, "no context on failure");
    expect(mcd_denoiser_create(NULL, &desc, &dn) == MCD_STATUS_INVALID_ARGUMENT,
           "denoiser on a NULL context");
    expect(mcd_denoiser_record(NULL, VK_NULL_HANDLE, 0, VK_NULL_HANDLE, 0, 0, &rec) ==
               MCD_STATUS_INVALID_ARGUMENT,
           "record on a NULL denoiser");
    expect(mcd_denoiser_run_host(NULL, NULL, 0, 0) == MCD_STATUS_INVALID_ARGUMENT,
           "run_host on a NULL denoiser");
    expect(mcd_denoiser_outputs(NULL, &out) == MCD_STATUS_INVALID_ARGUMENT, "outputs of NULL");
    expect(mcd_denoiser_reset(NULL) == MCD_STATUS_INVALID_ARGUMENT, "reset of NULL");
    expect(mcd_denoiser_read(NULL, NULL, NULL, NULL, 0) == MCD_STATUS_INVALID_ARGUMENT,
           "read of NULL");
    expect(mcd_context_use_pipeline_cache(NULL, "x", NULL) == MCD_STATUS_INVALID_ARGUMENT,
           "pipeline cache of NULL");
    expect(mcd_accum_bytes(NULL) == 0 && mcd_accum_bytes(&empty) == 0, "bytes of bad layouts");
    expect(mcd_accum_plane_count(&layout) == 21, "21 planes without position and visibility");
    expect(mcd_accum_plane_stride(&layout) == 512, "plane stride of 128 pixels: 512 bytes");
    expect(mcd_accum_bytes(&layout) == 21 * 512, "accumulation bytes");
    /* Destroying NULL is a no-op. */
    mcd_denoiser_destroy(NULL);
    mcd_context_destroy(NULL);
    mcd_recording_release(NULL);
    if (failures) {
        return 1;
    }
    printf("ok\n");
    return 0;
}
