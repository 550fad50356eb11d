//! The validation messenger really counts: a deliberately invalid Vulkan call must show up in the
//! report that every GPU test asserts empty.

use lensmap::gpu::vk;
use lensmap_tests::gpu;

#[test]
fn an_invalid_call_is_reported() {
    if std::env::var("LENSMAP_TEST_NO_VALIDATION").is_ok_and(|v| v == "1") {
        return;
    }
    let gpu = gpu();
    assert!(gpu.validation_report().messages.is_empty());
    // A buffer of size 0 violates VUID-VkBufferCreateInfo-size-00912.
    let info = vk::BufferCreateInfo::default()
        .size(0)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER)
        .sharing_mode(vk::SharingMode::EXCLUSIVE);
    // SAFETY: the call is invalid on purpose; the validation layer intercepts it, and the buffer
    // (if the driver returns one) is destroyed right away.
    unsafe {
        if let Ok(buffer) = gpu.device().create_buffer(&info, None) {
            gpu.device().destroy_buffer(buffer, None);
        }
    }
    let report = gpu.validation_report();
    assert!(report.enabled);
    assert!(
        report.messages.iter().any(|m| m.contains("size")),
        "expected a validation error, got {:?}",
        report.messages
    );
}
