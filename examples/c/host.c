/* A C renderer-shaped host of mcdenoise: its own Vulkan instance, device,
 * queue, command buffer and accumulation buffer, which its own compute
 * shader (accumulate.comp, built on include/mcdenoise_accum.glsl) fills.
 * It hands the buffer to mcdenoise, which records its chain into the
 * host's command buffer; the host submits, reads colour, error and the
 * sample map, then renders a second pass where the map says -- the map is
 * bound in the host's shader as it lies on the GPU -- and denoises again.
 *
 * Build: cc host.c -I../../include -lvulkan -L<dir of libmcdenoise> -lmcdenoise
 * Run:   ./host accumulate.spv [pipeline-cache-file]
 *        (capi/tests/c_example.rs does both)
 * With MCDENOISE_EMBED_VALIDATION=1 the host enables the Khronos
 * validation layer and fails on any message. Exits non-zero if the result
 * is wrong: the sample map must spend exactly the budget, and each
 * reconstruction must be closer to the noise-free image than the input. */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <vulkan/vulkan.h>

#include "mcdenoise.h"

#define W 64
#define H 48
#define SPP 8
#define BUDGET (W * H * 4)

#define VK_CHECK(call)                                                       \
    do {                                                                     \
        VkResult r_ = (call);                                                \
        if (r_ != VK_SUCCESS) {                                              \
            fprintf(stderr, "%s failed: %d (line %d)\n", #call, r_, __LINE__); \
            exit(1);                                                         \
        }                                                                    \
    } while (0)

static int messages = 0;

static VKAPI_ATTR VkBool32 VKAPI_CALL on_message(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT types,
    const VkDebugUtilsMessengerCallbackDataEXT *data, void *user)
{
    (void)severity; (void)types; (void)user;
    fprintf(stderr, "validation: %s\n", data->pMessage);
    messages++;
    return VK_FALSE;
}

/* The noise-free radiance at pixel (x, y) (accumulate.comp's `truth`). */
static float truth(int x, int y)
{
    return (x < W / 2 ? 0.2f : 1.0f) * (0.5f + (float)y / (float)H);
}

/* Relative MSE of an interleaved RGB image against truth(). */
static double rel_mse(const float *rgb)
{
    double sum = 0.0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                double t = truth(x, y), d = rgb[3 * (y * W + x) + c] - t;
                sum += d * d / (t * t + 0.01);
            }
    return sum / (3.0 * W * H);
}

static uint32_t memory_type(VkPhysicalDevice pd, uint32_t bits)
{
    VkPhysicalDeviceMemoryProperties props;
    vkGetPhysicalDeviceMemoryProperties(pd, &props);
    for (uint32_t i = 0; i < props.memoryTypeCount; i++)
        if ((bits & (1u << i)) &&
            (props.memoryTypes[i].propertyFlags & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT))
            return i;
    for (uint32_t i = 0; i < props.memoryTypeCount; i++)
        if (bits & (1u << i))
            return i;
    fprintf(stderr, "no memory type\n");
    exit(1);
}

static uint32_t *read_file(const char *path, size_t *bytes)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(1);
    }
    fseek(f, 0, SEEK_END);
    *bytes = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    uint32_t *words = malloc(*bytes);
    if (!words || fread(words, 1, *bytes, f) != *bytes) {
        fprintf(stderr, "cannot read %s\n", path);
        exit(1);
    }
    fclose(f);
    return words;
}

struct Push {
    uint32_t width, height, pass_index, uniform_spp, stride;
};

int main(int argc, char **argv)
{
    if (argc != 2 && argc != 3) {
        fprintf(stderr, "usage: %s accumulate.spv [pipeline-cache-file]\n", argv[0]);
        return 2;
    }
    if (mcd_api_version() != MCDENOISE_API_VERSION) {
        fprintf(stderr, "header version %d, library version %u\n", MCDENOISE_API_VERSION,
                mcd_api_version());
        return 1;
    }

    /* ---- The host renderer's own Vulkan objects (no mcdenoise involved). ---- */
    const char *v = getenv("MCDENOISE_EMBED_VALIDATION");
    int validate = v && strcmp(v, "1") == 0;
    const char *layers[] = {"VK_LAYER_KHRONOS_validation"};
    const char *exts[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
                             .apiVersion = VK_API_VERSION_1_1};
    VkInstanceCreateInfo ici = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                .pApplicationInfo = &app};
    if (validate) {
        ici.enabledLayerCount = 1;
        ici.ppEnabledLayerNames = layers;
        ici.enabledExtensionCount = 1;
        ici.ppEnabledExtensionNames = exts;
    }
    VkInstance instance;
    VK_CHECK(vkCreateInstance(&ici, NULL, &instance));
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    PFN_vkCreateDebugUtilsMessengerEXT create_messenger =
        (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(
            instance, "vkCreateDebugUtilsMessengerEXT");
    PFN_vkDestroyDebugUtilsMessengerEXT destroy_messenger =
        (PFN_vkDestroyDebugUtilsMessengerEXT)vkGetInstanceProcAddr(
            instance, "vkDestroyDebugUtilsMessengerEXT");
    if (validate) {
        VkDebugUtilsMessengerCreateInfoEXT mci = {
            .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
            .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT,
            .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                           VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT,
            .pfnUserCallback = on_message};
        VK_CHECK(create_messenger(instance, &mci, NULL, &messenger));
    }
    uint32_t count = 1;
    VkPhysicalDevice physical;
    VkResult er = vkEnumeratePhysicalDevices(instance, &count, &physical);
    if ((er != VK_SUCCESS && er != VK_INCOMPLETE) || count == 0) {
        fprintf(stderr, "no Vulkan device\n");
        return 1;
    }
    uint32_t families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, NULL);
    VkQueueFamilyProperties qprops[16];
    families = families > 16 ? 16 : families;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, qprops);
    uint32_t family = UINT32_MAX;
    for (uint32_t i = 0; i < families && family == UINT32_MAX; i++)
        if (qprops[i].queueFlags & VK_QUEUE_COMPUTE_BIT)
            family = i;
    if (family == UINT32_MAX) {
        fprintf(stderr, "no compute queue\n");
        return 1;
    }
    VkPhysicalDeviceFeatures supported, features = {0};
    vkGetPhysicalDeviceFeatures(physical, &supported);
    features.shaderFloat64 = supported.shaderFloat64;
    features.shaderInt64 = supported.shaderInt64;
    float prio = 1.0f;
    VkDeviceQueueCreateInfo qci = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                   .queueFamilyIndex = family,
                                   .queueCount = 1,
                                   .pQueuePriorities = &prio};
    VkDeviceCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                              .queueCreateInfoCount = 1,
                              .pQueueCreateInfos = &qci,
                              .pEnabledFeatures = &features};
    VkDevice device;
    VK_CHECK(vkCreateDevice(physical, &dci, NULL, &device));
    VkQueue queue;
    vkGetDeviceQueue(device, family, 0, &queue);

    /* The accumulation layout, and the buffer the host's shader fills. */
    McdAccumLayout layout = {.width = W, .height = H};
    uint64_t accum_bytes = mcd_accum_bytes(&layout);
    VkBufferCreateInfo bci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                              .size = accum_bytes,
                              .usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                       VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                                       VK_BUFFER_USAGE_TRANSFER_DST_BIT};
    VkBuffer accum;
    VK_CHECK(vkCreateBuffer(device, &bci, NULL, &accum));
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device, accum, &req);
    VkMemoryAllocateInfo mai = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .allocationSize = req.size,
                                .memoryTypeIndex = memory_type(physical, req.memoryTypeBits)};
    VkDeviceMemory memory;
    VK_CHECK(vkAllocateMemory(device, &mai, NULL, &memory));
    VK_CHECK(vkBindBufferMemory(device, accum, memory, 0));

    /* The host's accumulation pipeline. */
    size_t spv_bytes;
    uint32_t *spv = read_file(argv[1], &spv_bytes);
    VkShaderModuleCreateInfo smci = {.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
                                     .codeSize = spv_bytes,
                                     .pCode = spv};
    VkShaderModule module;
    VK_CHECK(vkCreateShaderModule(device, &smci, NULL, &module));
    free(spv);
    VkDescriptorSetLayoutBinding bindings[2] = {
        {.binding = 0, .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
         .descriptorCount = 1, .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT},
        {.binding = 1, .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
         .descriptorCount = 1, .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT}};
    VkDescriptorSetLayoutCreateInfo dslci = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
        .bindingCount = 2,
        .pBindings = bindings};
    VkDescriptorSetLayout set_layout;
    VK_CHECK(vkCreateDescriptorSetLayout(device, &dslci, NULL, &set_layout));
    VkPushConstantRange range = {VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(struct Push)};
    VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                       .setLayoutCount = 1,
                                       .pSetLayouts = &set_layout,
                                       .pushConstantRangeCount = 1,
                                       .pPushConstantRanges = &range};
    VkPipelineLayout pipeline_layout;
    VK_CHECK(vkCreatePipelineLayout(device, &plci, NULL, &pipeline_layout));
    VkComputePipelineCreateInfo cpci = {
        .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                  .module = module,
                  .pName = "main"},
        .layout = pipeline_layout};
    VkPipeline pipeline;
    VK_CHECK(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &cpci, NULL, &pipeline));
    VkDescriptorPoolSize pool_size = {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
    VkDescriptorPoolCreateInfo dpci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                       .maxSets = 1,
                                       .poolSizeCount = 1,
                                       .pPoolSizes = &pool_size};
    VkDescriptorPool pool;
    VK_CHECK(vkCreateDescriptorPool(device, &dpci, NULL, &pool));
    VkDescriptorSetAllocateInfo dsai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                        .descriptorPool = pool,
                                        .descriptorSetCount = 1,
                                        .pSetLayouts = &set_layout};
    VkDescriptorSet set;
    VK_CHECK(vkAllocateDescriptorSets(device, &dsai, &set));
    VkCommandPoolCreateInfo cpi = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                   .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                   .queueFamilyIndex = family};
    VkCommandPool cmd_pool;
    VK_CHECK(vkCreateCommandPool(device, &cpi, NULL, &cmd_pool));
    VkCommandBufferAllocateInfo cbai = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                        .commandPool = cmd_pool,
                                        .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                        .commandBufferCount = 1};
    VkCommandBuffer cmd;
    VK_CHECK(vkAllocateCommandBuffers(device, &cbai, &cmd));
    VkFenceCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence;
    VK_CHECK(vkCreateFence(device, &fci, NULL, &fence));

    /* ---- mcdenoise on the host's device. ---- */
    McdVulkanDevice host = {.instance = instance,
                            .physical_device = physical,
                            .device = device,
                            .queue = queue,
                            .queue_family_index = family,
                            .get_instance_proc_addr = vkGetInstanceProcAddr,
                            .shader_float64_enabled = features.shaderFloat64,
                            .shader_int64_enabled = features.shaderInt64};
    McdContext *ctx = NULL;
    McdDenoiser *denoiser = NULL;
    McdDenoiserDesc desc = {.layout = layout, .method = MCD_METHOD_WLR,
                            .flags = MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS};
    McdOutputs out;
    if (mcd_context_create(&host, &ctx) != MCD_STATUS_OK ||
        (argc == 3 && mcd_context_use_pipeline_cache(ctx, argv[2], NULL) != MCD_STATUS_OK) ||
        mcd_denoiser_create(ctx, &desc, &denoiser) != MCD_STATUS_OK ||
        mcd_denoiser_outputs(denoiser, &out) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    /* The host's shader reads mcdenoise's sample map where it lies. */
    VkDescriptorBufferInfo infos[2] = {{accum, 0, accum_bytes},
                                       {out.samples_buffer, out.samples_offset, 4 * W * H}};
    VkWriteDescriptorSet writes[2];
    for (int i = 0; i < 2; i++)
        writes[i] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                           .dstSet = set,
                                           .dstBinding = (uint32_t)i,
                                           .descriptorCount = 1,
                                           .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                           .pBufferInfo = &infos[i]};
    vkUpdateDescriptorSets(device, 2, writes, 0, NULL);

    static float color[3 * W * H], error[3 * W * H];
    static uint32_t samples[W * H];
    double first_rmse = 0.0;
    for (uint32_t pass = 0; pass < 2; pass++) {
        VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                          .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
        VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
        if (pass == 0) {
            vkCmdFillBuffer(cmd, accum, 0, VK_WHOLE_SIZE, 0);
            VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                  .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                  .dstAccessMask = VK_ACCESS_SHADER_READ_BIT |
                                                   VK_ACCESS_SHADER_WRITE_BIT};
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                 VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &mb, 0, NULL, 0,
                                 NULL);
        }
        /* The host's own pass: this pass's samples into the accumulation. */
        struct Push push = {W, H, pass, SPP, (uint32_t)(mcd_accum_plane_stride(&layout) / 4)};
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_layout, 0, 1, &set,
                                0, NULL);
        vkCmdPushConstants(cmd, pipeline_layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof push,
                           &push);
        vkCmdDispatch(cmd, (W * H + 63) / 64, 1, 1);
        /* mcdenoise's chain into the same command buffer (it brings its own
         * barriers): a sample map for the next pass after pass 0. */
        McdRecording *recording = NULL;
        if (mcd_denoiser_record(denoiser, cmd, family, accum, 0, pass == 0 ? BUDGET : 0, &recording) !=
            MCD_STATUS_OK) {
            fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
            return 1; /* the command buffer is discarded, never submitted */
        }
        VK_CHECK(vkEndCommandBuffer(cmd));
        VkSubmitInfo si = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                           .commandBufferCount = 1,
                           .pCommandBuffers = &cmd};
        VK_CHECK(vkQueueSubmit(queue, 1, &si, fence));
        VK_CHECK(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX));
        VK_CHECK(vkResetFences(device, 1, &fence));
        mcd_recording_release(recording);
        VK_CHECK(vkResetCommandBuffer(cmd, 0));

        if (mcd_denoiser_read(denoiser, color, error, pass == 0 ? samples : NULL, W * H) !=
            MCD_STATUS_OK) {
            fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
            return 1;
        }
        double rmse = rel_mse(color);
        /* The input's expected relative MSE: variance truth^2/3 over the
         * samples taken, relative to truth^2 (+0.01). */
        double input = 1.0 / (3.0 * SPP);
        printf("pass %u: rMSE %.5f (input about %.5f)\n", pass, rmse, input);
        if (!(rmse < 0.5 * input)) {
            fprintf(stderr, "pass %u: the reconstruction is not better than its input\n", pass);
            return 1;
        }
        if (pass == 0) {
            uint64_t total = 0;
            for (int i = 0; i < W * H; i++)
                total += samples[i];
            printf("sample map: %llu samples (budget %d)\n", (unsigned long long)total, BUDGET);
            if (total != BUDGET) {
                fprintf(stderr, "the sample map does not spend the budget\n");
                return 1;
            }
            first_rmse = rmse;
        } else if (!(rmse < first_rmse)) {
            fprintf(stderr, "the second pass did not lower the error\n");
            return 1;
        }
    }
    mcd_denoiser_destroy(denoiser);

    /* The same samples reconstructed with the pyramid's low band
     * (MCD_FLAG_PYRAMID): a denoiser of its own, recorded alone. */
    static float plain[3 * W * H];
    memcpy(plain, color, sizeof plain);
    desc.flags |= MCD_FLAG_PYRAMID;
    McdDenoiser *pyramid = NULL;
    McdRecording *recording = NULL;
    VkCommandBufferBeginInfo again = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                      .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    if (mcd_denoiser_create(ctx, &desc, &pyramid) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    VK_CHECK(vkBeginCommandBuffer(cmd, &again));
    if (mcd_denoiser_record(pyramid, cmd, family, accum, 0, 0, &recording) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    VK_CHECK(vkEndCommandBuffer(cmd));
    VkSubmitInfo psi = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                        .commandBufferCount = 1,
                        .pCommandBuffers = &cmd};
    VK_CHECK(vkQueueSubmit(queue, 1, &psi, fence));
    VK_CHECK(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX));
    VK_CHECK(vkResetFences(device, 1, &fence));
    mcd_recording_release(recording);
    if (mcd_denoiser_read(pyramid, color, error, NULL, W * H) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    double pyramid_rmse = rel_mse(color);
    printf("with the pyramid: rMSE %.5f\n", pyramid_rmse);
    if (memcmp(plain, color, sizeof plain) == 0 || !(pyramid_rmse < 1.0 / (6.0 * SPP))) {
        fprintf(stderr, "the pyramid's reconstruction is the plain one, or worse than half the input's error\n");
        return 1;
    }
    mcd_denoiser_destroy(pyramid);

    /* A stage's flag and its NO_ flag together are refused; each alone is
     * taken (the pyramid's and the input blend's). */
    const uint32_t stages[2][2] = {{MCD_FLAG_PYRAMID, MCD_FLAG_NO_PYRAMID},
                                   {MCD_FLAG_INPUT_BLEND, MCD_FLAG_NO_INPUT_BLEND}};
    for (int s = 0; s < 2; ++s) {
        for (int k = 0; k < 3; ++k) {
            McdDenoiserDesc probe_desc = desc;
            probe_desc.flags &= ~(MCD_FLAG_PYRAMID | MCD_FLAG_NO_PYRAMID);
            probe_desc.flags |= k < 2 ? stages[s][k] : stages[s][0] | stages[s][1];
            McdDenoiser *probe = NULL;
            enum McdStatus st = mcd_denoiser_create(ctx, &probe_desc, &probe);
            if (st != (k < 2 ? MCD_STATUS_OK : MCD_STATUS_INVALID_ARGUMENT)) {
                fprintf(stderr, "flags %#x: status %d (%s)\n", probe_desc.flags, (int)st,
                        mcd_last_error());
                return 1;
            }
            mcd_denoiser_destroy(probe);
        }
    }
    printf("stage flags: ok\n");

    /* A coarse sample map is an adaptive pass's: taken with
     * MCD_FLAG_ADAPTIVE_PASS, refused without it. */
    for (int k = 0; k < 2; ++k) {
        McdDenoiserDesc probe_desc = desc;
        probe_desc.flags &= ~(MCD_FLAG_PYRAMID | MCD_FLAG_NO_PYRAMID | MCD_FLAG_ADAPTIVE_PASS);
        probe_desc.flags |= MCD_FLAG_COARSE_MAP | (k == 0 ? MCD_FLAG_ADAPTIVE_PASS : 0u);
        McdDenoiser *probe = NULL;
        enum McdStatus st = mcd_denoiser_create(ctx, &probe_desc, &probe);
        if (st != (k == 0 ? MCD_STATUS_OK : MCD_STATUS_INVALID_ARGUMENT)) {
            fprintf(stderr, "coarse map, flags %#x: status %d (%s)\n", probe_desc.flags, (int)st,
                    mcd_last_error());
            return 1;
        }
        mcd_denoiser_destroy(probe);
    }
    printf("coarse map flag: ok\n");
    mcd_context_destroy(ctx);

    /* ---- The host's teardown. ---- */
    vkDestroyFence(device, fence, NULL);
    vkDestroyCommandPool(device, cmd_pool, NULL);
    vkDestroyDescriptorPool(device, pool, NULL);
    vkDestroyPipeline(device, pipeline, NULL);
    vkDestroyPipelineLayout(device, pipeline_layout, NULL);
    vkDestroyDescriptorSetLayout(device, set_layout, NULL);
    vkDestroyShaderModule(device, module, NULL);
    vkDestroyBuffer(device, accum, NULL);
    vkFreeMemory(device, memory, NULL);
    vkDestroyDevice(device, NULL);
    if (messenger != VK_NULL_HANDLE)
        destroy_messenger(instance, messenger, NULL);
    vkDestroyInstance(instance, NULL);
    if (messages > 0) {
        fprintf(stderr, "%d validation messages\n", messages);
        return 1;
    }
    printf("ok\n");
    return 0;
}
