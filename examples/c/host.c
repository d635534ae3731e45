/* A C renderer-shaped host of mcdenoise: its own Vulkan instance, device,
 * queue, command buffer and accumulation buffer, which its own compute
 * shader (accumulate.comp, built on include/mcdenoise_accum.glsl) fills.
 * It hands the buffer to mcdenoise, which records its chain into the
 * host's command buffer; the host submits, reads colour, error and the
 * sample map, then renders a second pass where the map says -- the map is
 * bound in the host's shader as it lies on the GPU -- and denoises again.
 * Then sums accumulated on the CPU, handed over in host memory
 * (mcd_denoiser_run_host). Last, an offline sequence: frames with the LP temporal filter and the
 * two-way filter (McdSmoother) over them.
 *
 * Build: cc host.c -I../../include -lvulkan -L<dir of libmcdenoise> -lmcdenoise
 * Run:   ./host accumulate.spv accumulate_position.spv [pipeline-cache-file]
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
    uint32_t width, height, pass_index, uniform_spp, stride, frame;
};

/* A device-local buffer of `size` bytes for the host's accumulation. */
static VkBuffer accumulation_buffer(VkDevice device, VkPhysicalDevice physical, uint64_t size,
                                    VkDeviceMemory *memory)
{
    VkBufferCreateInfo bci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                              .size = size,
                              .usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                       VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                                       VK_BUFFER_USAGE_TRANSFER_DST_BIT};
    VkBuffer buffer;
    VK_CHECK(vkCreateBuffer(device, &bci, NULL, &buffer));
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device, buffer, &req);
    VkMemoryAllocateInfo mai = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                .allocationSize = req.size,
                                .memoryTypeIndex = memory_type(physical, req.memoryTypeBits)};
    VK_CHECK(vkAllocateMemory(device, &mai, NULL, memory));
    VK_CHECK(vkBindBufferMemory(device, buffer, *memory, 0));
    return buffer;
}

/* The host's accumulation pipeline from the SPIR-V file `path`. */
static VkPipeline accumulation_pipeline(VkDevice device, const char *path,
                                        VkPipelineLayout layout, VkShaderModule *module)
{
    size_t spv_bytes;
    uint32_t *spv = read_file(path, &spv_bytes);
    VkShaderModuleCreateInfo smci = {.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
                                     .codeSize = spv_bytes,
                                     .pCode = spv};
    VK_CHECK(vkCreateShaderModule(device, &smci, NULL, module));
    free(spv);
    VkComputePipelineCreateInfo cpci = {
        .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                  .module = *module,
                  .pName = "main"},
        .layout = layout};
    VkPipeline pipeline;
    VK_CHECK(vkCreateComputePipelines(device, VK_NULL_HANDLE, 1, &cpci, NULL, &pipeline));
    return pipeline;
}

/* Points `set`'s bindings at the accumulation and the sample map. */
static void bind_buffers(VkDevice device, VkDescriptorSet set, VkBuffer accum, uint64_t accum_bytes,
                         VkBuffer samples, uint64_t samples_offset)
{
    VkDescriptorBufferInfo infos[2] = {{accum, 0, accum_bytes},
                                       {samples, samples_offset, 4 * W * H}};
    VkWriteDescriptorSet writes[2];
    for (int i = 0; i < 2; i++)
        writes[i] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                           .dstSet = set,
                                           .dstBinding = (uint32_t)i,
                                           .descriptorCount = 1,
                                           .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                           .pBufferInfo = &infos[i]};
    vkUpdateDescriptorSets(device, 2, writes, 0, NULL);
}

/* Submits `cmd` (recorded and ended), waits for it and resets it. */
static void submit_and_wait(VkDevice device, VkQueue queue, VkCommandBuffer cmd, VkFence fence)
{
    VkSubmitInfo si = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
                       .commandBufferCount = 1,
                       .pCommandBuffers = &cmd};
    VK_CHECK(vkQueueSubmit(queue, 1, &si, fence));
    VK_CHECK(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX));
    VK_CHECK(vkResetFences(device, 1, &fence));
    VK_CHECK(vkResetCommandBuffer(cmd, 0));
}

/* Begins `cmd` and records the host's accumulation pass into it: with
 * `clear`, the buffer zeroed first; then `push`'s samples added by
 * `pipeline` through `set`. */
static void record_accumulation(VkCommandBuffer cmd, VkPipeline pipeline, VkPipelineLayout layout,
                                VkDescriptorSet set, VkBuffer accum, int clear,
                                const struct Push *push)
{
    VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                      .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    if (clear) {
        vkCmdFillBuffer(cmd, accum, 0, VK_WHOLE_SIZE, 0);
        VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                              .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                              .dstAccessMask =
                                  VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT};
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &mb, 0, NULL, 0, NULL);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, NULL);
    vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof *push, push);
    vkCmdDispatch(cmd, (W * H + 63) / 64, 1, 1);
}

/* The frames of the sequence that mcd_smoother_finish hands back, and the
 * order it hands them in; `stop_at` makes the callback stop there. */
#define FRAMES 4
struct Sequence {
    float frames[FRAMES][3 * W * H];
    uint64_t order[FRAMES];
    uint64_t count;
    uint64_t stop_at;
};

static int32_t on_frame(void *user, uint64_t frame, const float *color, uint64_t pixels)
{
    struct Sequence *s = user;
    if (frame >= FRAMES || pixels != W * H || s->count >= FRAMES)
        return 2;
    memcpy(s->frames[frame], color, sizeof s->frames[frame]);
    s->order[s->count++] = frame;
    return s->count == s->stop_at ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc != 3 && argc != 4) {
        fprintf(stderr,
                "usage: %s accumulate.spv accumulate_position.spv [pipeline-cache-file]\n",
                argv[0]);
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
    VkDeviceMemory memory;
    VkBuffer accum = accumulation_buffer(device, physical, accum_bytes, &memory);

    /* The host's accumulation pipeline. */
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
    VkShaderModule module;
    VkPipeline pipeline = accumulation_pipeline(device, argv[1], pipeline_layout, &module);
    VkDescriptorPoolSize pool_size = {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 4};
    VkDescriptorPoolCreateInfo dpci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                       .maxSets = 2,
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
        (argc == 4 && mcd_context_use_pipeline_cache(ctx, argv[3], NULL) != MCD_STATUS_OK) ||
        mcd_denoiser_create(ctx, &desc, &denoiser) != MCD_STATUS_OK ||
        mcd_denoiser_outputs(denoiser, &out) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    /* The host's shader reads mcdenoise's sample map where it lies. */
    bind_buffers(device, set, accum, accum_bytes, out.samples_buffer, out.samples_offset);

    static float color[3 * W * H], error[3 * W * H];
    static uint32_t samples[W * H];
    double first_rmse = 0.0;
    for (uint32_t pass = 0; pass < 2; pass++) {
        /* The host's own pass: this pass's samples into the accumulation
         * (zeroed before the first). */
        struct Push push = {W, H, pass, SPP, (uint32_t)(mcd_accum_plane_stride(&layout) / 4), 0};
        record_accumulation(cmd, pipeline, pipeline_layout, set, accum, pass == 0, &push);
        /* mcdenoise's chain into the same command buffer (it brings its own
         * barriers): a sample map for the next pass after pass 0. */
        McdRecording *recording = NULL;
        if (mcd_denoiser_record(denoiser, cmd, family, accum, 0, pass == 0 ? BUDGET : 0, &recording) !=
            MCD_STATUS_OK) {
            fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
            return 1; /* the command buffer is discarded, never submitted */
        }
        VK_CHECK(vkEndCommandBuffer(cmd));
        submit_and_wait(device, queue, cmd, fence);
        mcd_recording_release(recording);

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
    submit_and_wait(device, queue, cmd, fence);
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

    /* A renderer that accumulates on the CPU: the same layout's planes in
     * host memory (Σx and Σx² per channel, then the count), handed over by
     * mcd_denoiser_run_host, which submits and waits itself. */
    {
        uint64_t stride = mcd_accum_plane_stride(&layout) / 4;
        uint64_t floats = mcd_accum_bytes(&layout) / 4;
        float *sums = calloc(floats, sizeof(float));
        static float mean[3 * W * H];
        uint32_t state = 12345u;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                uint64_t i = (uint64_t)y * W + x;
                for (int s = 0; s < SPP; s++) {
                    /* 10 channels: colour, albedo, normal, depth. */
                    float v[10] = {0, 0, 0, 1, 1, 1, 0, 0, 1, 2};
                    for (int c = 0; c < 3; c++) {
                        state = state * 1664525u + 1013904223u;
                        float u = (float)(state >> 8) / 16777216.0f;
                        v[c] = truth(x, y) * (0.4f + 1.2f * u);
                    }
                    for (int c = 0; c < 10; c++) {
                        sums[(2 * c) * stride + i] += v[c];
                        sums[(2 * c + 1) * stride + i] += v[c] * v[c];
                    }
                }
                sums[20 * stride + i] = SPP;
                for (int c = 0; c < 3; c++)
                    mean[3 * i + c] = sums[(2 * c) * stride + i] / SPP;
            }
        McdDenoiserDesc cpu_desc = {.layout = layout, .method = MCD_METHOD_WLR,
                                    .flags = MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS};
        McdDenoiser *cpu = NULL;
        if (mcd_denoiser_create(ctx, &cpu_desc, &cpu) != MCD_STATUS_OK ||
            mcd_denoiser_run_host(cpu, sums, floats * 4, 0) != MCD_STATUS_OK ||
            mcd_denoiser_read(cpu, color, NULL, NULL, W * H) != MCD_STATUS_OK) {
            fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
            return 1;
        }
        double in_rmse = rel_mse(mean), out_rmse = rel_mse(color);
        printf("sums in host memory: input rMSE %.5f, WLR %.5f\n", in_rmse, out_rmse);
        if (!(out_rmse < 0.5 * in_rmse)) {
            fprintf(stderr, "the host sums' reconstruction did not halve the input's error\n");
            return 1;
        }
        if (mcd_denoiser_run_host(cpu, sums, floats * 4 - 4, 0) != MCD_STATUS_INVALID_ARGUMENT) {
            fprintf(stderr, "sums of the wrong length were taken\n");
            return 1;
        }
        mcd_denoiser_destroy(cpu);
        free(sums);
    }

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

    /* ---- An offline sequence: FRAMES frames of the (static) scene, each
     * with noise of its own, through the temporal filter in frame order
     * (MCD_FLAG_TEMPORAL_LP, which reads the position sums: a layout and
     * a shader build with them) and both ways (McdSmoother). ---- */
    McdAccumLayout seq_layout = {.width = W, .height = H, .position = 1};
    uint64_t seq_bytes = mcd_accum_bytes(&seq_layout);
    VkDeviceMemory seq_memory;
    VkBuffer seq_accum = accumulation_buffer(device, physical, seq_bytes, &seq_memory);
    VkShaderModule seq_module;
    VkPipeline seq_pipeline = accumulation_pipeline(device, argv[2], pipeline_layout, &seq_module);
    McdDenoiserDesc seq_desc = {.layout = seq_layout, .method = MCD_METHOD_WLR,
                                .flags = MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS | MCD_FLAG_TEMPORAL_LP};
    McdDenoiser *filter = NULL;
    McdSmoother *smoother = NULL;
    McdOutputs seq_out;
    if (mcd_denoiser_create(ctx, &seq_desc, &filter) != MCD_STATUS_OK ||
        mcd_smoother_create(ctx, filter, &smoother) != MCD_STATUS_OK ||
        mcd_denoiser_outputs(filter, &seq_out) != MCD_STATUS_OK) {
        fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
        return 1;
    }
    VkDescriptorSet seq_set;
    VK_CHECK(vkAllocateDescriptorSets(device, &dsai, &seq_set));
    /* Binding 1 is not read in a first pass; any buffer of the size does. */
    bind_buffers(device, seq_set, seq_accum, seq_bytes, seq_out.samples_buffer,
                 seq_out.samples_offset);
    static struct Sequence both, stopped;
    static float forward[FRAMES][3 * W * H];
    for (int run = 0; run < 2; run++) {
        /* Run 1: a second sequence (after a reset) of two frames, whose
         * callback stops at its first frame. */
        uint32_t frames = run == 0 ? FRAMES : 2;
        if (run == 1 && mcd_denoiser_reset(filter) != MCD_STATUS_OK) {
            fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
            return 1;
        }
        for (uint32_t f = 0; f < frames; f++) {
            struct Push push = {W, H, 0, SPP, (uint32_t)(mcd_accum_plane_stride(&seq_layout) / 4),
                                1 + f + FRAMES * (uint32_t)run};
            record_accumulation(cmd, seq_pipeline, pipeline_layout, seq_set, seq_accum, 1, &push);
            McdRecording *rec = NULL;
            if (mcd_denoiser_record(filter, cmd, family, seq_accum, 0, 0, &rec) != MCD_STATUS_OK) {
                fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
                return 1;
            }
            VK_CHECK(vkEndCommandBuffer(cmd));
            submit_and_wait(device, queue, cmd, fence);
            mcd_recording_release(rec);
            /* The frame in frame order, then kept for the way back. */
            if ((run == 0 && mcd_denoiser_read(filter, forward[f], NULL, NULL, W * H) !=
                                 MCD_STATUS_OK) ||
                mcd_smoother_keep(smoother, filter) != MCD_STATUS_OK) {
                fprintf(stderr, "mcdenoise: %s\n", mcd_last_error());
                return 1;
            }
        }
        struct Sequence *seq = run == 0 ? &both : &stopped;
        seq->stop_at = run == 0 ? 0 : 1;
        uint64_t handed = 0;
        enum McdStatus st = mcd_smoother_finish(smoother, on_frame, seq, &handed);
        if (st != (run == 0 ? MCD_STATUS_OK : MCD_STATUS_INVALID_ARGUMENT) ||
            handed != (run == 0 ? FRAMES : 1)) {
            fprintf(stderr, "sequence %d: status %d, %llu frames handed (%s)\n", run, (int)st,
                    (unsigned long long)handed, mcd_last_error());
            return 1;
        }
    }
    /* Frames come back last first; every frame in both directions is
     * closer to the truth than in frame order on average, and the first,
     * which in frame order is the frame alone, by far. */
    double mean_forward = 0.0, mean_both = 0.0;
    for (int f = 0; f < FRAMES; f++) {
        if (both.order[f] != (uint64_t)(FRAMES - 1 - f)) {
            fprintf(stderr, "frame %d handed back as %llu\n", f,
                    (unsigned long long)both.order[f]);
            return 1;
        }
        mean_forward += rel_mse(forward[f]) / FRAMES;
        mean_both += rel_mse(both.frames[f]) / FRAMES;
    }
    double first_forward = rel_mse(forward[0]), first_both = rel_mse(both.frames[0]);
    printf("two-way: rMSE %.5f (frame 0 %.5f), in frame order %.5f (frame 0 %.5f)\n", mean_both,
           first_both, mean_forward, first_forward);
    if (!(mean_both < mean_forward) || !(first_both < 0.8 * first_forward)) {
        fprintf(stderr, "the two-way filter is not better than the filter in frame order\n");
        return 1;
    }
    /* After its finish the smoother starts a new sequence only after a
     * reset: keeping the denoiser's next frame without one is refused. */
    if (mcd_smoother_keep(smoother, filter) != MCD_STATUS_INVALID_ARGUMENT) {
        fprintf(stderr, "a keep without a reset was taken\n");
        return 1;
    }
    mcd_smoother_destroy(smoother);
    mcd_denoiser_destroy(filter);
    mcd_context_destroy(ctx);
    vkDestroyPipeline(device, seq_pipeline, NULL);
    vkDestroyShaderModule(device, seq_module, NULL);
    vkDestroyBuffer(device, seq_accum, NULL);
    vkFreeMemory(device, seq_memory, NULL);

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
