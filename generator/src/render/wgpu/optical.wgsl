// The optical tactile image's shading on the GPU: the same model as `sensors::optical` (its
// reference), step by step, from the optical depth views in the tactile atlas. Three dispatches per
// sensor view: indentation + the gel's spread along rows, along columns (the gel's surface: the
// larger of the indentation and its blur), then the slopes and the LEDs' shading. Markers, noise
// and quantization stay on the CPU (they need the sample's random stream).

struct Job {
    // Atlas x0, y0 of the view; its width, height.
    viewport: vec4<u32>,
    // First pixel of this view in the storage buffers; blur radius x, y (pixels); LED count.
    offset_radius: vec4<u32>,
    // Gel thickness (m), pixel pitch x, y (m), ambient light.
    geometry: vec4<f32>,
    // Spread sigma x, y (pixels; 0: no spread), vignetting, spread on (1) or off (0).
    spread: vec4<f32>,
    // The gel's tint (linear RGB).
    tint: vec4<f32>,
    // The depths the view sees: near, far plane (m); unused (z, w).
    depth_range: vec4<f32>,
    // Per LED: direction (normalised, towards the LED) and falloff; colour; azimuth (x, y normalised).
    light_dir: array<vec4<f32>, 8>,
    light_color: array<vec4<f32>, 8>,
    light_azimuth: array<vec4<f32>, 8>,
}

@group(0) @binding(0) var atlas: texture_2d<f32>;
@group(0) @binding(1) var<uniform> job: Job;
// Per pixel: the indentation blurred along its row (x), unused (y, z, w).
@group(0) @binding(2) var<storage, read_write> rows: array<f32>;
// Per pixel: linear R, G, B (before clipping) and the gel's surface (m).
@group(0) @binding(3) var<storage, read_write> shaded: array<vec4<f32>>;

fn indentation(x: i32, y: i32) -> f32 {
    let d = textureLoad(atlas, vec2<i32>(i32(job.viewport.x) + x, i32(job.viewport.y) + y), 0).x;
    let t = job.geometry.x;
    // +inf (no object), anything beyond the gel and a depth the view cannot see (the rasterizer
    // can carry an edge-on triangle's depth past its vertices; as `sensors::tactile` drops it)
    // leave it flat.
    if (!(d < t) || d < job.depth_range.x || d > job.depth_range.y) {
        return 0.0;
    }
    return clamp(t - d, 0.0, t);
}

fn gaussian(i: i32, sigma: f32) -> f32 {
    let s = f32(i) / sigma;
    return exp(-0.5 * s * s);
}

@compute @workgroup_size(8, 8)
fn blur_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = i32(job.viewport.z);
    let h = i32(job.viewport.w);
    let x = i32(id.x);
    let y = i32(id.y);
    if (x >= w || y >= h) {
        return;
    }
    var acc = 0.0;
    if (job.spread.w > 0.5) {
        let r = i32(job.offset_radius.y);
        var sum = 0.0;
        for (var i = -r; i <= r; i++) {
            let k = gaussian(i, job.spread.x);
            acc += k * indentation(clamp(x + i, 0, w - 1), y);
            sum += k;
        }
        acc = acc / sum;
    }
    rows[job.offset_radius.x + u32(y * w + x)] = acc;
}

@compute @workgroup_size(8, 8)
fn gel_surface(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = i32(job.viewport.z);
    let h = i32(job.viewport.w);
    let x = i32(id.x);
    let y = i32(id.y);
    if (x >= w || y >= h) {
        return;
    }
    let own = indentation(x, y);
    var gel = own;
    if (job.spread.w > 0.5) {
        let r = i32(job.offset_radius.z);
        var acc = 0.0;
        var sum = 0.0;
        for (var i = -r; i <= r; i++) {
            let k = gaussian(i, job.spread.y);
            acc += k * rows[job.offset_radius.x + u32(clamp(y + i, 0, h - 1) * w + x)];
            sum += k;
        }
        gel = max(own, acc / sum);
    }
    shaded[job.offset_radius.x + u32(y * w + x)] = vec4<f32>(0.0, 0.0, 0.0, gel);
}

fn gel_at(x: i32, y: i32) -> f32 {
    return shaded[job.offset_radius.x + u32(y * i32(job.viewport.z) + x)].w;
}

@compute @workgroup_size(8, 8)
fn shade(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = i32(job.viewport.z);
    let h = i32(job.viewport.w);
    let x = i32(id.x);
    let y = i32(id.y);
    if (x >= w || y >= h) {
        return;
    }
    let gel = gel_at(x, y);
    // Slopes: central differences, one-sided at the edges; zero where the gel is not displaced.
    var g = vec2<f32>(0.0, 0.0);
    if (gel != 0.0) {
        let x0 = max(x - 1, 0);
        let x1 = min(x + 1, w - 1);
        let y0 = max(y - 1, 0);
        let y1 = min(y + 1, h - 1);
        if (x1 > x0) {
            g.x = (gel_at(x1, y) - gel_at(x0, y)) / (f32(x1 - x0) * job.geometry.y);
        }
        if (y1 > y0) {
            g.y = (gel_at(x, y1) - gel_at(x, y0)) / (f32(y1 - y0) * job.geometry.z);
        }
    }
    let m = normalize(vec3<f32>(-g.x, -g.y, -1.0));
    let at = vec2<f32>((2.0 * f32(x) + 1.0) / f32(w) - 1.0, (2.0 * f32(y) + 1.0) / f32(h) - 1.0);
    var light = vec3<f32>(job.geometry.w);
    for (var i = 0u; i < job.offset_radius.w; i++) {
        let falloff = max(1.0 + job.light_dir[i].w * dot(job.light_azimuth[i].xy, at), 0.0);
        let lit = falloff * max(dot(m, job.light_dir[i].xyz), 0.0);
        light += lit * job.light_color[i].xyz;
    }
    let vignetting = 1.0 - job.spread.z * 0.5 * dot(at, at);
    shaded[job.offset_radius.x + u32(y * w + x)] = vec4<f32>(job.tint.xyz * vignetting * light, gel);
}
