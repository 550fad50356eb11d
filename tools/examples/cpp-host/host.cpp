// A C++17 host embedding lensmap through its C ABI, the way an engine would: it creates its own
// Vulkan instance and device (with the Khronos validation layer and synchronization validation
// when asked), creates a VkImage, asks lensmap to render a scene into it (lensmap records and
// submits on the host's queue and signals the host's timeline semaphore), reads the image back
// itself and writes an 8-bit sRGB PNG (and, with --pfm, the linear RGB as a PFM).
//
// Build (from the repository root, after `cargo build --release -p lensmap-capi`):
//   c++ -std=c++17 -O2 -Wall -Wextra -Werror -ffp-contract=off -I engine/capi/include
//       tools/examples/cpp-host/host.cpp -L target/release -llensmap_capi -lvulkan -o cpp-host
// Run:
//   LD_LIBRARY_PATH=target/release ./cpp-host --scene teapot-room --out out/cpp-host.png
//
// Options: --scene NAME|FILE  --bake DIR  --em-size N  --width W  --height H  --supersampling K
//          --format rgba8|rgba16f|rgba32f  --out FILE.png  --pfm FILE.pfm  --cycles N
//          --validation
// Exit status: 0 on success; 1 on any failure or any validation message.
//
// The PNG is encoded as lensmap's own (engine/src/trace/image.rs: srgb8), so the two files are
// equal byte for byte for the same frame; -ffp-contract=off keeps the compiler from fusing the
// encoding's multiply-add, which Rust never does.

#include <lensmap.h>
#include <vulkan/vulkan.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

// ---- failures -----------------------------------------------------------------------------

struct Failure : std::runtime_error {
    using std::runtime_error::runtime_error;
};

void check_vk(VkResult result, const char *call) {
    if (result != VK_SUCCESS) {
        throw Failure(std::string(call) + " failed: VkResult " + std::to_string(result));
    }
}

void check_lensmap(LensmapResult result, const char *call) {
    if (result != LENSMAP_RESULT_OK) {
        throw Failure(std::string(call) + " failed (" + std::to_string(result) +
                      "): " + lensmap_last_error());
    }
}

// ---- options ------------------------------------------------------------------------------

struct Options {
    std::string scene = "teapot-room";
    std::string bake;
    uint32_t em_size = 0;
    uint32_t width = 0, height = 0, supersampling = 0;  // 0: the scene camera's
    std::string format = "rgba16f";
    std::string out = "out/cpp-host.png";
    std::string pfm;
    int cycles = 1;
    bool validation = false;
};

uint32_t number(const char *text, const char *flag) {
    char *end = nullptr;
    unsigned long value = std::strtoul(text, &end, 10);
    if (end == text || *end != '\0' || value > 1u << 20) {
        throw Failure(std::string(flag) + ": '" + text + "' is not a count");
    }
    return static_cast<uint32_t>(value);
}

Options parse(int argc, char **argv) {
    Options options;
    for (int i = 1; i < argc; i++) {
        std::string flag = argv[i];
        if (flag == "--validation") {
            options.validation = true;
            continue;
        }
        if (i + 1 >= argc) {
            throw Failure(flag + " needs a value (or is not an option)");
        }
        const char *value = argv[++i];
        if (flag == "--scene") options.scene = value;
        else if (flag == "--bake") options.bake = value;
        else if (flag == "--em-size") options.em_size = number(value, "--em-size");
        else if (flag == "--width") options.width = number(value, "--width");
        else if (flag == "--height") options.height = number(value, "--height");
        else if (flag == "--supersampling") options.supersampling = number(value, "--supersampling");
        else if (flag == "--format") options.format = value;
        else if (flag == "--out") options.out = value;
        else if (flag == "--pfm") options.pfm = value;
        else if (flag == "--cycles") options.cycles = static_cast<int>(number(value, "--cycles"));
        else throw Failure("unknown option " + flag);
    }
    return options;
}

// lensmap's framebuffer format and the image format the host gives it (the same precision, so
// the image holds exactly what `lensmap render` reads back).
struct Format {
    uint32_t lensmap;
    VkFormat vulkan;
    uint32_t bytes;
};

Format format_of(const std::string &name) {
    if (name == "rgba8") return {LENSMAP_FORMAT_RGBA8, VK_FORMAT_R8G8B8A8_UNORM, 4};
    if (name == "rgba16f") return {LENSMAP_FORMAT_RGBA16F, VK_FORMAT_R16G16B16A16_SFLOAT, 8};
    if (name == "rgba32f") return {LENSMAP_FORMAT_RGBA32F, VK_FORMAT_R32G32B32A32_SFLOAT, 16};
    throw Failure("--format " + name + ": give rgba8, rgba16f or rgba32f");
}

// ---- image files --------------------------------------------------------------------------

float half_to_float(uint16_t h) {
    uint32_t sign = static_cast<uint32_t>(h >> 15) << 31;
    uint32_t exponent = (h >> 10) & 0x1f;
    uint32_t mantissa = h & 0x3ff;
    uint32_t bits;
    if (exponent == 0) {
        if (mantissa == 0) {
            bits = sign;
        } else {  // subnormal: normalize
            int shift = 0;
            while ((mantissa & 0x400) == 0) {
                mantissa <<= 1;
                shift++;
            }
            mantissa &= 0x3ff;
            bits = sign | static_cast<uint32_t>(127 - 15 + 1 - shift) << 23 | mantissa << 13;
        }
    } else if (exponent == 31) {
        bits = sign | 0x7f800000u | mantissa << 13;
    } else {
        bits = sign | (exponent + 127 - 15) << 23 | mantissa << 13;
    }
    float value;
    std::memcpy(&value, &bits, sizeof value);
    return value;
}

// lensmap's sRGB transfer function (srgb_encode): clamped to [0, 1], NaN to 0.
float srgb_encode(float linear) {
    float c = std::isnan(linear) ? 0.0f : std::fmin(std::fmax(linear, 0.0f), 1.0f);
    if (c <= 0.0031308f) return 12.92f * c;
    return 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

uint32_t crc32(const uint8_t *data, size_t size, uint32_t crc = 0) {
    crc = ~crc;
    for (size_t i = 0; i < size; i++) {
        crc ^= data[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

void put32(std::vector<uint8_t> &out, uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<uint8_t>(v >> shift));
}

void chunk(std::vector<uint8_t> &png, const char *type, const std::vector<uint8_t> &data) {
    put32(png, static_cast<uint32_t>(data.size()));
    std::vector<uint8_t> body(type, type + 4);
    body.insert(body.end(), data.begin(), data.end());
    png.insert(png.end(), body.begin(), body.end());
    put32(png, crc32(body.data(), body.size()));
}

// An 8-bit RGB PNG with stored (uncompressed) deflate blocks: a PNG writer in 40 lines, so the
// example needs no library beyond Vulkan and lensmap.
void write_png(const std::string &path, uint32_t width, uint32_t height,
               const std::vector<uint8_t> &rgb) {
    std::vector<uint8_t> raw;
    raw.reserve((3 * width + 1) * height);
    for (uint32_t y = 0; y < height; y++) {
        raw.push_back(0);  // filter: none
        raw.insert(raw.end(), rgb.begin() + 3 * width * y, rgb.begin() + 3 * width * (y + 1));
    }
    std::vector<uint8_t> zlib = {0x78, 0x01};
    uint32_t a = 1, b = 0;
    for (uint8_t byte : raw) {
        a = (a + byte) % 65521;
        b = (b + a) % 65521;
    }
    for (size_t offset = 0; offset < raw.size() || offset == 0; offset += 65535) {
        size_t length = std::min<size_t>(65535, raw.size() - offset);
        zlib.push_back(offset + length == raw.size() ? 1 : 0);
        zlib.push_back(static_cast<uint8_t>(length));
        zlib.push_back(static_cast<uint8_t>(length >> 8));
        zlib.push_back(static_cast<uint8_t>(~length));
        zlib.push_back(static_cast<uint8_t>(~length >> 8));
        zlib.insert(zlib.end(), raw.begin() + offset, raw.begin() + offset + length);
        if (raw.empty()) break;
    }
    put32(zlib, b << 16 | a);
    std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    std::vector<uint8_t> header;
    put32(header, width);
    put32(header, height);
    header.insert(header.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, no filter, no interlace
    chunk(png, "IHDR", header);
    chunk(png, "IDAT", zlib);
    chunk(png, "IEND", {});
    std::ofstream file(path, std::ios::binary);
    file.write(reinterpret_cast<const char *>(png.data()), static_cast<std::streamsize>(png.size()));
    if (!file) throw Failure("writing " + path + " failed");
}

// Linear RGB as a little-endian PFM (rows bottom to top, as the format has them).
void write_pfm(const std::string &path, uint32_t width, uint32_t height,
               const std::vector<float> &rgba) {
    std::ofstream file(path, std::ios::binary);
    file << "PF\n" << width << " " << height << "\n-1.0\n";
    for (uint32_t row = 0; row < height; row++) {
        uint32_t y = height - 1 - row;
        for (uint32_t x = 0; x < width; x++) {
            file.write(reinterpret_cast<const char *>(&rgba[4 * (y * width + x)]), 3 * sizeof(float));
        }
    }
    if (!file) throw Failure("writing " + path + " failed");
}

// ---- Vulkan -------------------------------------------------------------------------------

uint64_t validation_messages = 0;

VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT,
                                          VkDebugUtilsMessageTypeFlagsEXT,
                                          const VkDebugUtilsMessengerCallbackDataEXT *data, void *) {
    validation_messages++;
    std::fprintf(stderr, "validation: %s\n", data->pMessage ? data->pMessage : "(no message)");
    return VK_FALSE;
}

uint32_t memory_type(VkPhysicalDevice physical, uint32_t allowed, VkMemoryPropertyFlags wanted) {
    VkPhysicalDeviceMemoryProperties properties;
    vkGetPhysicalDeviceMemoryProperties(physical, &properties);
    for (uint32_t i = 0; i < properties.memoryTypeCount; i++) {
        if ((allowed & (1u << i)) && (properties.memoryTypes[i].propertyFlags & wanted) == wanted) {
            return i;
        }
    }
    throw Failure("no memory type with the properties needed");
}

// The host's own Vulkan objects, destroyed in reverse order of creation.
struct Host {
    VkInstance instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    VkDevice device = VK_NULL_HANDLE;
    uint32_t family = 0;
    VkQueue queue = VK_NULL_HANDLE;

    // The constructor releases what it made before rethrowing (a destructor runs only after a
    // constructor that finished).
    explicit Host(bool validation) {
        try {
            create(validation);
        } catch (...) {
            release();
            throw;
        }
    }

    void create(bool validation) {
        VkApplicationInfo app{};
        app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
        app.pApplicationName = "lensmap cpp-host";
        app.apiVersion = VK_API_VERSION_1_3;
        const char *layer = "VK_LAYER_KHRONOS_validation";
        const char *extension = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
        VkDebugUtilsMessengerCreateInfoEXT messenger_info{};
        messenger_info.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
        messenger_info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                         VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
        messenger_info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                                     VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
        messenger_info.pfnUserCallback = on_message;
        VkValidationFeatureEnableEXT synchronization =
            VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
        VkValidationFeaturesEXT features{};
        features.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT;
        features.enabledValidationFeatureCount = 1;
        features.pEnabledValidationFeatures = &synchronization;
        features.pNext = &messenger_info;
        VkInstanceCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
        info.pApplicationInfo = &app;
        if (validation) {
            info.enabledLayerCount = 1;
            info.ppEnabledLayerNames = &layer;
            info.enabledExtensionCount = 1;
            info.ppEnabledExtensionNames = &extension;
            info.pNext = &features;
        }
        check_vk(vkCreateInstance(&info, nullptr, &instance), "vkCreateInstance");
        if (validation) {
            auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
                vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
            if (!create) throw Failure("no vkCreateDebugUtilsMessengerEXT");
            check_vk(create(instance, &messenger_info, nullptr, &messenger),
                     "vkCreateDebugUtilsMessengerEXT");
        }
        uint32_t count = 0;
        vkEnumeratePhysicalDevices(instance, &count, nullptr);
        std::vector<VkPhysicalDevice> devices(count);
        vkEnumeratePhysicalDevices(instance, &count, devices.data());
        for (VkPhysicalDevice candidate : devices) {
            VkPhysicalDeviceProperties properties;
            vkGetPhysicalDeviceProperties(candidate, &properties);
            if (properties.apiVersion < VK_API_VERSION_1_3) continue;
            uint32_t families = 0;
            vkGetPhysicalDeviceQueueFamilyProperties(candidate, &families, nullptr);
            std::vector<VkQueueFamilyProperties> family_properties(families);
            vkGetPhysicalDeviceQueueFamilyProperties(candidate, &families, family_properties.data());
            for (uint32_t f = 0; f < families; f++) {
                if (family_properties[f].queueFlags & VK_QUEUE_GRAPHICS_BIT) {
                    physical = candidate;
                    family = f;
                    break;
                }
            }
            if (physical != VK_NULL_HANDLE) break;
        }
        if (physical == VK_NULL_HANDLE) throw Failure("no Vulkan 1.3 device with a graphics queue");
        // What lensmap needs (LENSMAP_FEATURES_REQUIRED), enabled by the host.
        VkPhysicalDeviceVulkan13Features vulkan13{};
        vulkan13.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES;
        vulkan13.dynamicRendering = VK_TRUE;
        vulkan13.synchronization2 = VK_TRUE;
        VkPhysicalDeviceVulkan12Features vulkan12{};
        vulkan12.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES;
        vulkan12.timelineSemaphore = VK_TRUE;
        vulkan12.pNext = &vulkan13;
        VkPhysicalDeviceFeatures2 features2{};
        features2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
        features2.features.imageCubeArray = VK_TRUE;
        features2.pNext = &vulkan12;
        float priority = 1.0f;
        VkDeviceQueueCreateInfo queue_info{};
        queue_info.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
        queue_info.queueFamilyIndex = family;
        queue_info.queueCount = 1;
        queue_info.pQueuePriorities = &priority;
        VkDeviceCreateInfo device_info{};
        device_info.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
        device_info.pNext = &features2;
        device_info.queueCreateInfoCount = 1;
        device_info.pQueueCreateInfos = &queue_info;
        check_vk(vkCreateDevice(physical, &device_info, nullptr, &device), "vkCreateDevice");
        vkGetDeviceQueue(device, family, 0, &queue);
    }

    ~Host() { release(); }

    void release() noexcept {
        if (device != VK_NULL_HANDLE) vkDestroyDevice(device, nullptr);
        if (messenger != VK_NULL_HANDLE) {
            auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
                vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
            if (destroy) destroy(instance, messenger, nullptr);
        }
        if (instance != VK_NULL_HANDLE) vkDestroyInstance(instance, nullptr);
        device = VK_NULL_HANDLE;
        messenger = VK_NULL_HANDLE;
        instance = VK_NULL_HANDLE;
    }
    Host(const Host &) = delete;
    Host &operator=(const Host &) = delete;
};

// The host's image, its view, a timeline semaphore, a readback buffer and a command buffer.
struct Target {
    VkDevice device;
    VkImage image = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
    VkDeviceMemory image_memory = VK_NULL_HANDLE;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory buffer_memory = VK_NULL_HANDLE;
    VkSemaphore done = VK_NULL_HANDLE;
    VkCommandPool pool = VK_NULL_HANDLE;
    VkFence fence = VK_NULL_HANDLE;

    Target(const Host &host, VkFormat format, uint32_t width, uint32_t height, uint32_t bytes)
        : device(host.device) {
        try {
            create(host, format, width, height, bytes);
        } catch (...) {
            release();
            throw;
        }
    }

    void create(const Host &host, VkFormat format, uint32_t width, uint32_t height,
                uint32_t bytes) {
        VkImageCreateInfo image_info{};
        image_info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
        image_info.imageType = VK_IMAGE_TYPE_2D;
        image_info.format = format;
        image_info.extent = {width, height, 1};
        image_info.mipLevels = 1;
        image_info.arrayLayers = 1;
        image_info.samples = VK_SAMPLE_COUNT_1_BIT;
        image_info.tiling = VK_IMAGE_TILING_OPTIMAL;
        image_info.usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
        image_info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        check_vk(vkCreateImage(device, &image_info, nullptr, &image), "vkCreateImage");
        VkMemoryRequirements needs;
        vkGetImageMemoryRequirements(device, image, &needs);
        VkMemoryAllocateInfo allocation{};
        allocation.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        allocation.allocationSize = needs.size;
        allocation.memoryTypeIndex =
            memory_type(host.physical, needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        check_vk(vkAllocateMemory(device, &allocation, nullptr, &image_memory), "vkAllocateMemory");
        check_vk(vkBindImageMemory(device, image, image_memory, 0), "vkBindImageMemory");
        VkImageViewCreateInfo view_info{};
        view_info.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        view_info.image = image;
        view_info.viewType = VK_IMAGE_VIEW_TYPE_2D;
        view_info.format = format;
        view_info.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        check_vk(vkCreateImageView(device, &view_info, nullptr, &view), "vkCreateImageView");

        VkBufferCreateInfo buffer_info{};
        buffer_info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
        buffer_info.size = VkDeviceSize{width} * height * bytes;
        buffer_info.usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
        check_vk(vkCreateBuffer(device, &buffer_info, nullptr, &buffer), "vkCreateBuffer");
        vkGetBufferMemoryRequirements(device, buffer, &needs);
        allocation.allocationSize = needs.size;
        allocation.memoryTypeIndex = memory_type(
            host.physical, needs.memoryTypeBits,
            VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
        check_vk(vkAllocateMemory(device, &allocation, nullptr, &buffer_memory), "vkAllocateMemory");
        check_vk(vkBindBufferMemory(device, buffer, buffer_memory, 0), "vkBindBufferMemory");

        VkSemaphoreTypeCreateInfo timeline{};
        timeline.sType = VK_STRUCTURE_TYPE_SEMAPHORE_TYPE_CREATE_INFO;
        timeline.semaphoreType = VK_SEMAPHORE_TYPE_TIMELINE;
        VkSemaphoreCreateInfo semaphore_info{};
        semaphore_info.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
        semaphore_info.pNext = &timeline;
        check_vk(vkCreateSemaphore(device, &semaphore_info, nullptr, &done), "vkCreateSemaphore");
        VkCommandPoolCreateInfo pool_info{};
        pool_info.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
        pool_info.queueFamilyIndex = host.family;
        check_vk(vkCreateCommandPool(device, &pool_info, nullptr, &pool), "vkCreateCommandPool");
        VkFenceCreateInfo fence_info{};
        fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
        check_vk(vkCreateFence(device, &fence_info, nullptr, &fence), "vkCreateFence");
    }

    ~Target() { release(); }

    // Destroying VK_NULL_HANDLE is a no-op, so this undoes a partly finished create() too.
    void release() noexcept {
        vkDeviceWaitIdle(device);
        vkDestroyFence(device, fence, nullptr);
        vkDestroyCommandPool(device, pool, nullptr);
        vkDestroySemaphore(device, done, nullptr);
        vkDestroyBuffer(device, buffer, nullptr);
        vkFreeMemory(device, buffer_memory, nullptr);
        vkDestroyImageView(device, view, nullptr);
        vkDestroyImage(device, image, nullptr);
        vkFreeMemory(device, image_memory, nullptr);
    }
    Target(const Target &) = delete;
    Target &operator=(const Target &) = delete;

    // Copies the image (left in TRANSFER_SRC_OPTIMAL by lensmap) into the buffer once `done`
    // reaches `value`, and waits.
    void read_back(const Host &host, uint32_t width, uint32_t height, uint64_t value) {
        VkCommandBufferAllocateInfo allocate{};
        allocate.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
        allocate.commandPool = pool;
        allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
        allocate.commandBufferCount = 1;
        VkCommandBuffer cb;
        check_vk(vkAllocateCommandBuffers(device, &allocate, &cb), "vkAllocateCommandBuffers");
        VkCommandBufferBeginInfo begin{};
        begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
        begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
        check_vk(vkBeginCommandBuffer(cb, &begin), "vkBeginCommandBuffer");
        VkBufferImageCopy region{};
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageExtent = {width, height, 1};
        vkCmdCopyImageToBuffer(cb, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1, &region);
        VkMemoryBarrier2 to_host{};
        to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER_2;
        to_host.srcStageMask = VK_PIPELINE_STAGE_2_COPY_BIT;
        to_host.srcAccessMask = VK_ACCESS_2_TRANSFER_WRITE_BIT;
        to_host.dstStageMask = VK_PIPELINE_STAGE_2_HOST_BIT;
        to_host.dstAccessMask = VK_ACCESS_2_HOST_READ_BIT;
        VkDependencyInfo dependency{};
        dependency.sType = VK_STRUCTURE_TYPE_DEPENDENCY_INFO;
        dependency.memoryBarrierCount = 1;
        dependency.pMemoryBarriers = &to_host;
        vkCmdPipelineBarrier2(cb, &dependency);
        check_vk(vkEndCommandBuffer(cb), "vkEndCommandBuffer");
        VkSemaphoreSubmitInfo wait{};
        wait.sType = VK_STRUCTURE_TYPE_SEMAPHORE_SUBMIT_INFO;
        wait.semaphore = done;
        wait.value = value;
        wait.stageMask = VK_PIPELINE_STAGE_2_COPY_BIT;
        VkCommandBufferSubmitInfo buffer_info{};
        buffer_info.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_SUBMIT_INFO;
        buffer_info.commandBuffer = cb;
        VkSubmitInfo2 submit{};
        submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO_2;
        submit.waitSemaphoreInfoCount = 1;
        submit.pWaitSemaphoreInfos = &wait;
        submit.commandBufferInfoCount = 1;
        submit.pCommandBufferInfos = &buffer_info;
        check_vk(vkQueueSubmit2(host.queue, 1, &submit, fence), "vkQueueSubmit2");
        check_vk(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
        check_vk(vkResetFences(device, 1, &fence), "vkResetFences");
        vkFreeCommandBuffers(device, pool, 1, &cb);
    }
};

// lensmap's handles, freed on every path.
struct Lensmap {
    LensmapContext *context = nullptr;
    LensmapScene *scene = nullptr;
    ~Lensmap() {
        lensmap_scene_free(scene);
        lensmap_context_free(context);
    }
};

// One create / render / read back / free cycle; the last one writes the files.
void cycle(const Options &options, bool write) {
    Host host(options.validation);
    Lensmap lensmap;
    LensmapHostDevice lent{};
    lent.struct_size = sizeof lent;
    lent.get_instance_proc_addr = vkGetInstanceProcAddr;
    lent.instance = host.instance;
    lent.physical_device = host.physical;
    lent.device = host.device;
    lent.queue_family = host.family;
    lent.queue = host.queue;
    lent.enabled_features = LENSMAP_FEATURES_REQUIRED;
    check_lensmap(lensmap_context_new_on_host(&lent, &lensmap.context), "lensmap_context_new_on_host");

    LensmapSceneOptions scene{};
    scene.struct_size = sizeof scene;
    scene.scene = options.scene.c_str();
    scene.bake_dir = options.bake.empty() ? nullptr : options.bake.c_str();
    scene.em_size = options.em_size;
    check_lensmap(lensmap_scene_load(&scene, &lensmap.scene), "lensmap_scene_load");

    LensmapFrameOptions frame{};
    frame.struct_size = sizeof frame;
    check_lensmap(lensmap_scene_frame_options(lensmap.scene, &frame), "lensmap_scene_frame_options");
    Format format = format_of(options.format);
    frame.format = format.lensmap;
    if (options.width) frame.width = options.width;
    if (options.height) frame.height = options.height;
    if (options.supersampling) frame.supersampling = options.supersampling;

    Target target(host, format.vulkan, frame.width, frame.height, format.bytes);
    const uint64_t ready = 1;
    LensmapHostImage image{};
    image.struct_size = sizeof image;
    image.image = target.image;
    image.view = target.view;
    image.mip_level = 0;
    image.array_layer = 0;
    image.format = format.vulkan;
    image.current_layout = VK_IMAGE_LAYOUT_UNDEFINED;
    image.final_layout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    image.signal_count = 1;
    image.signal_semaphores = &target.done;
    image.signal_values = &ready;
    LensmapFrameStats stats{};
    stats.struct_size = sizeof stats;
    check_lensmap(lensmap_render_to_image(lensmap.context, lensmap.scene, &frame, &image, &stats),
                  "lensmap_render_to_image");
    target.read_back(host, frame.width, frame.height, ready);

    if (write) {
        size_t pixels = size_t{frame.width} * frame.height;
        void *mapped = nullptr;
        check_vk(vkMapMemory(host.device, target.buffer_memory, 0, VK_WHOLE_SIZE, 0, &mapped),
                 "vkMapMemory");
        std::vector<float> rgba(4 * pixels);
        const auto *bytes = static_cast<const uint8_t *>(mapped);
        for (size_t i = 0; i < 4 * pixels; i++) {
            if (format.bytes == 4) {
                rgba[i] = static_cast<float>(bytes[i]) / 255.0f;
            } else if (format.bytes == 8) {
                uint16_t h;
                std::memcpy(&h, bytes + 2 * i, 2);
                rgba[i] = half_to_float(h);
            } else {
                std::memcpy(&rgba[i], bytes + 4 * i, 4);
            }
        }
        vkUnmapMemory(host.device, target.buffer_memory);
        std::vector<uint8_t> rgb(3 * pixels);
        for (size_t p = 0; p < pixels; p++) {
            for (size_t c = 0; c < 3; c++) {
                rgb[3 * p + c] = static_cast<uint8_t>(srgb_encode(rgba[4 * p + c]) * 255.0f + 0.5f);
            }
        }
        write_png(options.out, frame.width, frame.height, rgb);
        if (!options.pfm.empty()) write_pfm(options.pfm, frame.width, frame.height, rgba);
        std::printf("%s: %ux%u (%ux%u subpixels), %u passes, CPU %.1f ms (trace %.1f, texgen %.1f, "
                    "tessellation %.1f, other %.1f), %llu rays\n",
                    options.out.c_str(), frame.width, frame.height,
                    frame.width * frame.supersampling, frame.height * frame.supersampling,
                    stats.passes, stats.total_ms, stats.trace_ms, stats.texgen_ms,
                    stats.tessellation_ms, stats.other_ms,
                    static_cast<unsigned long long>(stats.rays));
    }
}

}  // namespace

int main(int argc, char **argv) {
    try {
        Options options = parse(argc, argv);
        for (int i = 0; i < options.cycles; i++) cycle(options, i + 1 == options.cycles);
    } catch (const std::exception &failure) {
        std::fprintf(stderr, "cpp-host: %s\n", failure.what());
        return 1;
    }
    if (validation_messages != 0) {
        std::fprintf(stderr, "cpp-host: %llu validation message(s)\n",
                     static_cast<unsigned long long>(validation_messages));
        return 1;
    }
    return 0;
}
