// Main-view shader: glTF metallic-roughness shading (GGX) of a textured mesh under a spotlight
// with a filtered shadow map and an ambient hemisphere, in linear light written to an sRGB target;
// plus the exact z-depth in metres, the instance mask id and the target object's unoccluded
// silhouette, in one pass with four colour targets.
// `vs_shadow` is the depth-only pass that renders the shadow map from the spotlight.

struct Frame {
    view: mat4x4<f32>,        // world -> camera (OpenCV)
    proj: mat4x4<f32>,        // camera -> clip
    light_pos: vec4<f32>,     // camera frame; w: distance from the light to its target
    light_color: vec4<f32>,   // rgb: colour x intensity; w: 1 = shade, 0 = unlit pass
    ambient: vec4<f32>,       // rgb; w: 1 = shadows on
    light_dir: vec4<f32>,     // camera frame, the spot's axis; w: cos(outer angle)
    spot: vec4<f32>,          // x: cos(inner angle); y: shadow-map texel size at 1 m; z: 1 = ACES tonemapping
    up: vec4<f32>,            // world up in the camera frame
    shadow_vp: mat4x4<f32>,   // camera frame -> the light's clip space
};

struct Instance {
    model_view: mat4x4<f32>,  // model -> camera
    normal_mat: mat4x4<f32>,  // inverse-transpose of model_view
    mask_id: vec4<u32>,
};

struct MaterialFactors {
    roughness_metallic: vec4<f32>,   // z: texture-coordinate scale
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<uniform> inst: Instance;
@group(2) @binding(0) var base_color: texture_2d<f32>;
@group(2) @binding(1) var base_sampler: sampler;
@group(2) @binding(2) var<uniform> material: MaterialFactors;
@group(3) @binding(0) var shadow_map: texture_depth_2d;
@group(3) @binding(1) var shadow_sampler: sampler_comparison;

const PI: f32 = 3.14159265;

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

// The shadow pass: `model_view` is model -> light frame, `proj` the light's projection.
@vertex
fn vs_shadow(v: VsIn) -> @builtin(position) vec4<f32> {
    return frame.proj * inst.model_view * vec4<f32>(v.position, 1.0);
}

struct FsOut {
    @location(0) color: vec4<f32>,
    @location(1) depth: f32,
    @location(2) mask: u32,
    // 1 where the target object is drawn; only its pipeline writes this target.
    @location(3) silhouette: u32,
};

// Share of a 3x3 PCF kernel (each tap a bilinear 2x2 comparison) lit by the spotlight. The lookup point is pushed off the surface
// along the light-facing normal by ~1.5 shadow texels (normal-offset bias: no acne on surfaces
// grazing the light), which together with the small slope-scaled bias of the shadow pass keeps
// contact shadows attached (no peter-panning at the finger-object contacts).
fn shadow_factor(cam_pos: vec3<f32>, n_light: vec3<f32>, dist: f32) -> f32 {
    let texel = frame.spot.y * dist;
    let p = frame.shadow_vp * vec4<f32>(cam_pos + n_light * (1.5 * texel), 1.0);
    if (p.w <= 0.0) {
        return 1.0;
    }
    let ndc = p.xyz / p.w;
    let uv = vec2<f32>(0.5 + 0.5 * ndc.x, 0.5 - 0.5 * ndc.y);
    if (uv.x < 0.0 || uv.x > 1.0 || uv.y < 0.0 || uv.y > 1.0 || ndc.z > 1.0) {
        return 1.0;
    }
    let size = vec2<f32>(textureDimensions(shadow_map));
    var lit = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            lit += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + vec2<f32>(f32(dx), f32(dy)) * (1.5 / size), ndc.z);
        }
    }
    return lit / 9.0;
}

fn aces(x: vec3<f32>) -> vec3<f32> {
    // Narkowicz's fit of the ACES filmic curve.
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
}

@fragment
fn fs_main(i: VsOut) -> FsOut {
    var o: FsOut;
    // Perspective-correct interpolation of the camera-frame position gives the exact point of the
    // triangle seen through this pixel centre, so this is the analytic z-depth.
    o.depth = i.cam_pos.z;
    o.mask = inst.mask_id.x;
    o.silhouette = 1u;
    // Depth and mask passes (unlit) discard the colour: skip the texture lookup and shading.
    if (frame.light_color.w < 0.5) {
        o.color = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    } else {
        o.color = shade(i);
    }
    return o;
}

// The multisampled colour pass (`renderer.msaa` > 1): colour only, resolved to the colour target;
// depth and mask stay exact, from the single-sample pass.
@fragment
fn fs_color(i: VsOut) -> @location(0) vec4<f32> {
    return shade(i);
}

fn shade(i: VsOut) -> vec4<f32> {
    let albedo = textureSample(base_color, base_sampler, i.uv * material.roughness_metallic.z).rgb;
    if (frame.light_color.w < 0.5) {
        return vec4<f32>(albedo, 1.0);
    }
    let rough = clamp(material.roughness_metallic.x, 0.04, 1.0);
    let metal = clamp(material.roughness_metallic.y, 0.0, 1.0);
    let v = normalize(-i.cam_pos);
    var n = normalize(i.normal);
    // Two-sided: thin parts and open meshes are lit from the side the camera sees.
    if (dot(n, v) < 0.0) {
        n = -n;
    }
    let to_light = frame.light_pos.xyz - i.cam_pos;
    let dist = length(to_light);
    let l = to_light / dist;
    let n_dot_l = max(dot(n, l), 0.0);
    let n_dot_v = max(dot(n, v), 1e-4);
    // Spot cone and inverse-square falloff, normalised to 1 at the target's distance.
    let spot = smoothstep(frame.light_dir.w, frame.spot.x, dot(-l, frame.light_dir.xyz));
    let falloff = min((frame.light_pos.w * frame.light_pos.w) / (dist * dist), 4.0);
    var n_light = n;
    if (dot(n_light, l) < 0.0) {
        n_light = -n_light;
    }
    var shadow = 1.0;
    // Only where the light reaches at all: most of the floor and backdrop skip the lookups.
    if (frame.ambient.w > 0.5 && n_dot_l > 0.0 && spot > 0.0) {
        shadow = shadow_factor(i.cam_pos, n_light, dist);
    }
    // Cook-Torrance: GGX distribution, Smith-Schlick geometry, Schlick Fresnel.
    let h = normalize(l + v);
    let a = rough * rough;
    let a2 = a * a;
    let n_dot_h = max(dot(n, h), 0.0);
    let d_term = a2 / (PI * pow(n_dot_h * n_dot_h * (a2 - 1.0) + 1.0, 2.0));
    let k = (rough + 1.0) * (rough + 1.0) / 8.0;
    let g = (n_dot_v / (n_dot_v * (1.0 - k) + k)) * (n_dot_l / (n_dot_l * (1.0 - k) + k));
    let f0 = mix(vec3<f32>(0.04), albedo, metal);
    let f = f0 + (vec3<f32>(1.0) - f0) * pow(1.0 - max(dot(h, v), 0.0), 5.0);
    let specular = d_term * g * f / (4.0 * n_dot_v * max(n_dot_l, 1e-4));
    let diffuse = (vec3<f32>(1.0) - f) * (1.0 - metal) * albedo / PI;
    // Irradiance scaled so that a white matte surface facing the light at the target's distance
    // shows the light's colour x intensity.
    let radiance = frame.light_color.rgb * (PI * spot * falloff * shadow);
    let direct = (diffuse + specular) * radiance * n_dot_l;
    // Ambient hemisphere: brighter from above than from the floor; metals reflect it.
    let hemi = mix(0.55, 1.0, 0.5 + 0.5 * dot(n, frame.up.xyz));
    let ambient = frame.ambient.rgb * hemi * (albedo * (1.0 - metal) + f0 * 0.5);
    var color = direct + ambient;
    if (frame.spot.z > 0.5) {
        color = aces(color);
    }
    return vec4<f32>(color, 1.0);
}
