//! Embree errors come back as `Err` with Embree's own message, never as a crash.
#![cfg(embree)]

use goniospec::accel::embree::{BufferKind, Device, ErrorKind, Scene, TriangleGeometry};

#[test]
fn misaligned_buffer_stride_is_an_error() {
    let dev = Device::new("").expect("default device");
    let mut g = TriangleGeometry::new(&dev).unwrap();
    let data = vec![0u32; 64];
    let err = g
        .set_shared_buffer(BufferKind::Vertex, &data, 6, 3)
        .expect_err("a 6-byte stride is not 4-byte aligned");
    assert_eq!(err.kind, ErrorKind::InvalidOperation);
    assert!(err.message.contains("aligned"), "{err}");
    assert!(err.to_string().contains("Vertex buffer"), "{err}");
    // The device is still usable and its error state was cleared.
    dev.check("after the error").expect("error was consumed");
}

#[test]
fn buffer_too_small_is_refused_before_embree_reads_it() {
    let dev = Device::new("").unwrap();
    let mut g = TriangleGeometry::new(&dev).unwrap();
    let err = g
        .set_shared_buffer(BufferKind::Index, &[0, 1, 2], 12, 5)
        .expect_err("5 triangles need 60 bytes");
    assert_eq!(err.kind, ErrorKind::InvalidArgument);
    assert!(err.message.contains("need 60 B"), "{err}");
}

#[test]
fn committing_a_scene_with_an_incomplete_geometry_is_an_error() {
    let dev = Device::new("").unwrap();
    let mut scene = Scene::new(&dev).unwrap();
    scene.attach(TriangleGeometry::new(&dev).unwrap()).unwrap();
    let err = scene.commit().expect_err("geometry without buffers");
    assert!(err.to_string().contains("committing the scene"), "{err}");
    assert!(!err.message.is_empty());
}

#[test]
fn invalid_device_configuration_is_an_error() {
    let err = Device::new("threads=abc")
        .err()
        .expect("bad thread count refused");
    assert!(err.to_string().contains("threads=abc"), "{err}");
    let err = Device::new("a\0b").err().expect("NUL refused");
    assert!(err.message.contains("NUL"), "{err}");
}

#[test]
fn version_is_read_from_the_library() {
    let v = Device::new("").unwrap().version();
    assert!(v.major == 3 || v.major == 4, "{v}");
    assert_eq!(v.major, goniospec::accel::embree::EMBREE_MAJOR);
}
