// The depth map rasteriser's shaders (src/oracle/oracle_gpu.rs).
//
// The vertex shader passes positions through; the resolve fragment shader
// writes the occluder's value. `flat` keeps the value bit-exact (an
// interpolated constant could come out an ulp lower). The count fragment
// shader writes nothing that is kept: the count pass only updates the
// stencil buffer.

struct VsOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) value: f32,
}

@vertex
fn vs_main(@location(0) v: vec4<f32>) -> VsOut {
    var out: VsOut;
    out.position = vec4<f32>(v.x, v.y, v.z, 1.0);
    out.value = v.w;
    return out;
}

@fragment
fn fs_count() -> @location(0) vec4<f32> {
    return vec4<f32>(0.0, 0.0, 0.0, 0.0);
}

@fragment
fn fs_resolve(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(in.value, 0.0, 0.0, 0.0);
}
