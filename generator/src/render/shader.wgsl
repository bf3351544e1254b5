// Main-view shader: textured, lit colour (linear, written to an sRGB target), exact z-depth in
// metres, and the instance mask id, in one pass with three colour targets.

struct Frame {
    view: mat4x4<f32>,        // world -> camera (OpenCV)
    proj: mat4x4<f32>,        // camera -> clip
    light_pos: vec4<f32>,     // camera frame
    light_color: vec4<f32>,
    ambient: vec4<f32>,
};

struct Instance {
    model_view: mat4x4<f32>,  // model -> camera
    normal_mat: mat4x4<f32>,  // inverse-transpose of model_view
    mask_id: vec4<u32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<uniform> inst: Instance;
@group(2) @binding(0) var base_color: texture_2d<f32>;
@group(2) @binding(1) var base_sampler: sampler;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
};

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) cam_pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
};

@vertex
fn vs_main(v: VsIn) -> VsOut {
    var o: VsOut;
    let cam = inst.model_view * vec4<f32>(v.position, 1.0);
    o.cam_pos = cam.xyz;
    o.clip = frame.proj * cam;
    o.normal = (inst.normal_mat * vec4<f32>(v.normal, 0.0)).xyz;
    o.uv = v.uv;
    return o;
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) depth: f32,
    @location(2) mask: u32,
};

@fragment
fn fs_main(i: VsOut) -> FsOut {
    var o: FsOut;
    let albedo = textureSample(base_color, base_sampler, i.uv).rgb;
    let to_eye = normalize(-i.cam_pos);
    var n = normalize(i.normal);
    // Two-sided: thin parts and open meshes are lit from the side the camera sees.
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    let to_light = normalize(frame.light_pos.xyz - i.cam_pos);
    let diffuse = max(dot(n, to_light), 0.0);
    let half_v = normalize(to_light + to_eye);
    let spec = 0.12 * pow(max(dot(n, half_v), 0.0), 40.0) * step(0.0, diffuse);
    let lit = albedo * (frame.ambient.rgb + diffuse * frame.light_color.rgb) + spec * frame.light_color.rgb;
    o.color = vec4<f32>(lit, 1.0);
    // Perspective-correct interpolation of the camera-frame position gives the exact point of the
    // triangle seen through this pixel centre, so this is the analytic z-depth.
    o.depth = i.cam_pos.z;
    o.mask = inst.mask_id.x;
    return o;
}
