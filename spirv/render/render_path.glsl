// The built-in path tracer's shared part: materials, BSDFs, light
// sampling and one camera path (trace_sample), included by render_trace
// (the samples) and render_features (features from samples of their own,
// RENDER-FEATURE-SAMPLES). The including kernel includes
// render_scene.glsl (bindings 0-4) first; the workgroup, the push block
// and bindings 5-9 below are both kernels', so that one descriptor set
// and one push serve both (render_features does not read Scan). With
// FEATURES_ONLY defined, trace_sample stops once the features are taken:
// the camera path up to the first surface that is not a smooth mirror,
// and the visibility's shadow ray at the first vertex (none where that is
// smooth), as the samples take it.

layout(local_size_x = 64) in;

// Mirrors mcdenoise::render::TracePush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;          // first grid row of the band (Batch::dispatch)
    uint item0;         // the window's first item (of the pass)
    uint items;         // items in the window
    uint seed_lo;
    uint seed_hi;
    uint uniform_spp;   // > 0: every pixel has this many samples (no search)
} push;

// Per pixel: (exclusive prefix of the pass's counts, count plane at the
// start of the pass); entry width * height holds (total, 0) (render_scan).
layout(std430, set = 0, binding = 5) readonly buffer Scan { uvec2 scan[]; };
// Four uvec4 per item of the window: the float bits of the 14 values in
// AccumLayout channel order (colour, albedo, normal, depth, position,
// visibility), then the pixel (NO_PIXEL past the pass's samples) and the
// sample index. Read by render_resolve (and Renderer::run_pass_debug);
// render_features rewrites the feature values.
layout(std430, set = 0, binding = 6) buffer Items { uvec4 items[]; };
// Per-vertex shading normals: three vec4 per entry; a triangle's entry
// index is in the bits of its p3.w (0xffffffff: flat).
layout(std430, set = 0, binding = 7) readonly buffer Normals { vec4 vnormals[]; };
// Traversal counters since the renderer's last reset: rays (low, high
// word), BVH node visits (low, high word).
layout(std430, set = 0, binding = 8) buffer Work { uint work[]; };
// Placements of keyframed objects back to the scene file's: three vec4
// (the rows of a 3x4 affine map) per entry, entry 0 the identity; a
// primitive's entry is in bits 16-22 of its p0.w (GpuScene::rest).
layout(std430, set = 0, binding = 9) readonly buffer Rest { vec4 rest[]; };

// Where the point p_ref of primitive i at shutter time 0 lies in its
// object's placement as the scene file writes it: the position feature
// and the textures' coordinates, so that a point on a keyframed object
// keeps both from frame to frame (spec §10.1's W; RENDER-REST).
vec3 rest_position(uint i, vec3 p_ref)
{
    uint r = floatBitsToUint(prims[4u * i].w) >> 16u;
    if (r == 0u) {
        return p_ref;
    }
    vec4 q = vec4(p_ref, 1.0);
    return vec3(dot(rest[3u * r], q), dot(rest[3u * r + 1u], q), dot(rest[3u * r + 2u], q));
}

// The pixel of an item past the pass's samples (render_resolve skips it).
#define NO_PIXEL 0xffffffffu

// Random dimensions (pairs): camera 0-1, then 4 per path vertex.
#define DIM_PIXEL 0u
#define DIM_LENS 1u
#define DIM_TIME 2u
#define DIM_VERTEX 4u

// ---------------------------------------------------------------- materials
float hash31(vec3 p)
{
    uvec4 h = pcg4d(uvec4(ivec4(floor(p), 0x51ED27u)));
    return float(h.x >> 8u) * (1.0 / 16777216.0);
}

float value_noise(vec3 p)
{
    vec3 i = floor(p);
    vec3 f = p - i;
    vec3 s = f * f * (3.0 - 2.0 * f);
    float n000 = hash31(i);
    float n100 = hash31(i + vec3(1, 0, 0));
    float n010 = hash31(i + vec3(0, 1, 0));
    float n110 = hash31(i + vec3(1, 1, 0));
    float n001 = hash31(i + vec3(0, 0, 1));
    float n101 = hash31(i + vec3(1, 0, 1));
    float n011 = hash31(i + vec3(0, 1, 1));
    float n111 = hash31(i + vec3(1, 1, 1));
    return mix(mix(mix(n000, n100, s.x), mix(n010, n110, s.x), s.y),
               mix(mix(n001, n101, s.x), mix(n011, n111, s.x), s.y), s.z);
}

// Colour of material m at the rest position p (rest_position): the albedo of diffuse
// and plastic materials, the radiance of emitters (constant or textured).
vec3 albedo_at(uint m, vec3 p)
{
    vec4 m0 = mats[3u * m];
    uint tex = floatBitsToUint(m0.x) >> 8u;
    vec3 a = mats[3u * m + 1u].xyz;
    vec3 b = mats[3u * m + 2u].xyz;
    if (tex == TEX_CHECKER) {
        ivec3 c = ivec3(floor(p * m0.y + 1e-4));
        return ((c.x + c.y + c.z) & 1) == 0 ? a : b;
    }
    if (tex == TEX_NOISE) {
        vec3 q = p * m0.y;
        float n = 0.5333 * value_noise(q) + 0.2667 * value_noise(2.03 * q) + 0.2 * value_noise(4.01 * q);
        return mix(a, b, n);
    }
    return a;
}

// The albedo feature of an emitter of radiance le (RENDER-FEATURES):
// le / (1 + le) per channel, so an emitter brighter than 1 keeps its
// pattern in the feature.
vec3 emission_feature(vec3 le)
{
    return le / (vec3(1.0) + le);
}

// ---------------------------------------------------------------- BSDFs
// GGX (Trowbridge-Reitz) microfacets with separable Smith masking; visible
// normals sampled after Heitz 2018. Vectors in world space; n faces wo.
void frame(vec3 n, out vec3 t, out vec3 b)
{
    t = normalize(abs(n.x) > 0.5 ? cross(n, vec3(0, 1, 0)) : cross(n, vec3(1, 0, 0)));
    b = cross(n, t);
}

float ggx_d(float cos_h, float a)
{
    float a2 = a * a;
    float k = cos_h * cos_h * (a2 - 1.0) + 1.0;
    return a2 / (PI * k * k);
}

float ggx_g1(float cos_w, float a)
{
    float c2 = max(cos_w * cos_w, 1e-8);
    float tan2 = max(1.0 - c2, 0.0) / c2;
    return 2.0 / (1.0 + sqrt(1.0 + a * a * tan2));
}

// A visible normal for direction wo (cos_o > 0).
vec3 ggx_sample_h(vec3 n, vec3 wo, float a, vec2 u)
{
    vec3 t, b;
    frame(n, t, b);
    vec3 wl = vec3(dot(wo, t), dot(wo, b), dot(wo, n));
    vec3 vh = normalize(vec3(a * wl.x, a * wl.y, wl.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = len2 > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    vec3 hl = normalize(vec3(a * nh.x, a * nh.y, max(1e-6, nh.z)));
    return hl.x * t + hl.y * b + hl.z * n;
}

vec3 schlick(vec3 f0, float c)
{
    float m = clamp(1.0 - c, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (1.0 - f0) * (m2 * m2 * m);
}

// Unpolarised Fresnel reflectance at a dielectric interface; eta = η_t/η_i.
float fresnel_dielectric(float cos_i, float eta)
{
    cos_i = clamp(cos_i, 0.0, 1.0);
    float sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin_t2 >= 1.0) {
        return 1.0;
    }
    float cos_t = sqrt(1.0 - sin_t2);
    float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// Probability of sampling the specular lobe of plastic.
float plastic_spec_prob(float cos_o, float ior, vec3 alb)
{
    float f = fresnel_dielectric(cos_o, ior);
    float d = (1.0 - f) * max(alb.r, max(alb.g, alb.b));
    return clamp(f / max(f + d, 1e-6), 0.1, 0.9);
}

// BSDF × cos for a non-delta material, and the pdf of sampling wi.
vec3 bsdf_eval(uint cls, vec3 alb, float a, float ior, vec3 n, vec3 wo, vec3 wi, out float pdf)
{
    float ci = dot(n, wi);
    float co = dot(n, wo);
    pdf = 0.0;
    if (ci <= 0.0 || co <= 0.0) {
        return vec3(0.0);
    }
    if (cls == MAT_DIFFUSE) {
        pdf = ci / PI;
        return alb * (ci / PI);
    }
    vec3 h = normalize(wo + wi);
    float d = ggx_d(dot(n, h), a);
    float g1o = ggx_g1(co, a);
    float spec_pdf = d * g1o / (4.0 * co);
    float g = g1o * ggx_g1(ci, a);
    float spec = d * g / (4.0 * co);   // × cos_i already
    if (cls == MAT_CONDUCTOR) {
        pdf = spec_pdf;
        return schlick(alb, dot(wo, h)) * spec;
    }
    // Plastic: a GGX dielectric coat over a diffuse base.
    float f = fresnel_dielectric(dot(wo, h), ior);
    float ps = plastic_spec_prob(co, ior, alb);
    pdf = ps * spec_pdf + (1.0 - ps) * ci / PI;
    vec3 base = alb * ((1.0 - fresnel_dielectric(co, ior)) * (1.0 - fresnel_dielectric(ci, ior)) * ci / PI);
    return vec3(f * spec) + base;
}

// ---------------------------------------------------------------- sampling
vec3 cosine_hemisphere(vec3 n, vec2 u)
{
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    vec3 t, b;
    frame(n, t, b);
    return normalize(r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0.0, 1.0 - u.x)) * n);
}

vec2 concentric_disk(vec2 u)
{
    vec2 o = 2.0 * u - 1.0;
    if (o.x == 0.0 && o.y == 0.0) {
        return vec2(0.0);
    }
    float r, th;
    if (abs(o.x) > abs(o.y)) {
        r = o.x;
        th = (PI / 4.0) * (o.y / o.x);
    } else {
        r = o.y;
        th = (PI / 2.0) - (PI / 4.0) * (o.x / o.y);
    }
    return r * vec2(cos(th), sin(th));
}

// 1 - sqrt(1 - x) without cancellation for small x.
float one_minus_sqrt1m(float x)
{
    return x / (1.0 + sqrt(max(0.0, 1.0 - x)));
}

// Whether next-event estimation samples sphere `prim` by the cone it
// subtends from p (p outside the sphere) rather than by area.
bool sphere_cone(uint prim, vec3 p, float time, out vec3 c, out float r2, out float d2)
{
    c = prims[4u * prim].xyz + time * prims[4u * prim + 3u].xyz;
    r2 = prims[4u * prim + 1u].w * prims[4u * prim + 1u].w;
    vec3 to_c = c - p;
    d2 = dot(to_c, to_c);
    return (floatBitsToUint(prims[4u * prim].w) & 3u) == KIND_SPHERE && d2 > r2 * 1.0001;
}

// Solid-angle density, selection included, with which next-event
// estimation from p picks the direction to point q of light `prim`
// (dist2 = |q − p|², cos_l the cosine at q).
float light_pdf(uint prim, vec3 p, float dist2, float cos_l, float time)
{
    float pdf_area = prims[4u * prim + 2u].w;   // selection / area
    vec3 c;
    float r2, d2;
    if (sphere_cone(prim, p, time, c, r2, d2)) {
        float select = pdf_area * 4.0 * PI * r2;
        return select / (2.0 * PI * one_minus_sqrt1m(r2 / d2));
    }
    return pdf_area * dist2 / max(cos_l, 1e-8);
}

// Picks a light (by power) and a point on it as seen from p at shutter
// time `time`: uniform in the cone a sphere subtends, uniform by area on a
// quad or a triangle (or on a sphere around p). Returns the point and its
// unit normal; a triangle emits on both sides, so its normal is the one
// facing p.
void sample_light(vec2 u_sel, vec2 u, vec3 p, float time, out vec3 pos, out vec3 nrm, out uint prim)
{
    prim = floatBitsToUint(lights[select_light(u_sel.x)].x);
    vec4 p0 = prims[4u * prim];
    vec4 p1 = prims[4u * prim + 1u];
    vec4 p2 = prims[4u * prim + 2u];
    vec3 motion = prims[4u * prim + 3u].xyz;
    vec3 c;
    float r2, d2;
    if (sphere_cone(prim, p, time, c, r2, d2)) {
        float d = sqrt(d2);
        vec3 wc = (c - p) / d;
        float omc = one_minus_sqrt1m(r2 / d2);   // 1 − cos θmax
        float v = u.x * omc;                      // 1 − cos θ
        float cos_t = 1.0 - v;
        float sin2 = v * (2.0 - v);
        float phi = 2.0 * PI * u.y;
        vec3 t, b;
        frame(wc, t, b);
        vec3 dir = cos_t * wc + sqrt(sin2) * (cos(phi) * t + sin(phi) * b);
        float dist = d * cos_t - sqrt(max(0.0, r2 - d2 * sin2));
        pos = p + dist * dir;
        nrm = normalize(pos - c);
    } else if ((floatBitsToUint(p0.w) & 3u) == KIND_SPHERE) {
        float z = 1.0 - 2.0 * u.x;
        float r = sqrt(max(0.0, 1.0 - z * z));
        float phi = 2.0 * PI * u.y;
        nrm = vec3(r * cos(phi), r * sin(phi), z);
        pos = p0.xyz + p1.w * nrm + time * motion;
    } else if ((floatBitsToUint(p0.w) & 3u) == KIND_TRIANGLE) {
        // Uniform by area: barycentrics (1 − √u, √u (1 − v), √u v).
        float su = sqrt(u.x);
        pos = p0.xyz + (su * (1.0 - u.y)) * p1.xyz + (su * u.y) * p2.xyz + time * motion;
        nrm = normalize(cross(p1.xyz, p2.xyz));
        nrm = dot(nrm, p - pos) < 0.0 ? -nrm : nrm;
    } else {
        pos = p0.xyz + u.x * p1.xyz + u.y * p2.xyz + time * motion;
        nrm = normalize(cross(p1.xyz, p2.xyz));
    }
}

float power_heuristic(float a, float b)
{
    float a2 = a * a;
    return a2 / (a2 + b * b);
}

// Geometric normal of primitive i at world point p (shutter time `time`).
vec3 normal_at(uint i, vec3 p, float time)
{
    vec4 p0 = prims[4u * i];
    vec4 p1 = prims[4u * i + 1u];
    uint kind = floatBitsToUint(p0.w) & 3u;
    if (kind == KIND_SPHERE) {
        return normalize(p - time * prims[4u * i + 3u].xyz - p0.xyz);
    }
    return normalize(cross(p1.xyz, prims[4u * i + 2u].xyz));
}

// Interpolated shading normal of primitive i at reference-time point p, or
// the geometric normal ng when it has none.
vec3 shading_normal(uint i, vec3 p, vec3 ng)
{
    uint k = floatBitsToUint(prims[4u * i + 3u].w);
    if (k == 0xffffffffu) {
        return ng;
    }
    vec3 a = prims[4u * i].xyz;
    vec3 e1 = prims[4u * i + 1u].xyz;
    vec3 e2 = prims[4u * i + 2u].xyz;
    vec3 c = cross(e1, e2);
    float inv = 1.0 / dot(c, c);
    vec3 ap = p - a;
    float u = dot(cross(ap, e2), c) * inv;
    float v = dot(cross(e1, ap), c) * inv;
    vec3 ns = (1.0 - u - v) * vnormals[3u * k].xyz + u * vnormals[3u * k + 1u].xyz + v * vnormals[3u * k + 2u].xyz;
    float len = length(ns);
    return len > 0.0 ? ns / len : ng;
}

vec3 offset_origin(vec3 p, vec3 n)
{
    float mag = max(max(abs(p.x), abs(p.y)), max(abs(p.z), 1.0));
    return p + n * (1e-4 * mag);
}

// ---------------------------------------------------------------- one sample
// Traces one camera path. Outputs the 14 channel values in AccumLayout order.
void trace_sample(uvec4 key, uvec2 pix, out vec3 color, out vec3 albedo, out vec3 normal,
                  out float depth, out vec3 position, out float visibility)
{
    color = vec3(0.0);
    albedo = vec3(0.0);
    normal = vec3(0.0);
    depth = 0.0;
    position = vec3(0.0);
    visibility = 0.0;

    vec2 jitter = rand2(key, DIM_PIXEL);
    vec2 lens = rand2(key, DIM_LENS);
    float time = rand2(key, DIM_TIME).x;
    vec2 ndc = vec2(2.0 * (float(pix.x) + jitter.x) / float(push.width) - 1.0,
                    1.0 - 2.0 * (float(pix.y) + jitter.y) / float(push.height));
    vec3 target = P.cam_pos.xyz + P.focus_w.xyz + ndc.x * P.half_u.xyz + ndc.y * P.half_v.xyz;
    vec2 disk = P.cam_pos.w * concentric_disk(lens);
    vec3 o = P.cam_pos.xyz + disk.x * P.lens_u.xyz + disk.y * P.lens_v.xyz;
    vec3 d = normalize(target - o);

    vec3 beta = vec3(1.0);
    float prev_bsdf_pdf = 0.0;   // 0: the previous vertex was the camera
    // The albedo and normal features are still to be taken, times feat_tint.
    bool feat_open = true;
    vec3 feat_tint = vec3(1.0);
    uint max_depth = P.counts.z;
    for (uint depth_i = 0u; depth_i <= max_depth; depth_i++) {
        Hit h = trace(o, d, time, 0.0, T_INF, false);
        if (h.prim < 0) {
            color += beta * P.env.rgb;
            if (feat_open && depth_i > 0u) {
                albedo = vec3(0.0);   // a mirror showing the sky: as a miss
            }
            break;
        }
        uint prim = uint(h.prim);
        vec3 p = o + h.t * d;
        vec3 ng = normal_at(prim, p, time);
        bool front = dot(ng, d) < 0.0;
        vec3 ngf = front ? ng : -ng;   // geometric, facing the ray
        uint m = prim_material(prim);
        uint mkind = floatBitsToUint(mats[3u * m].x) & 255u;
        vec3 p_ref = p - time * prims[4u * prim + 3u].xyz;
        vec3 p_rest = rest_position(prim, p_ref);
        // Shading normal on the ray's side; the geometric one where the
        // interpolated normal faces away from the viewer.
        vec3 n = shading_normal(prim, p_ref, ng);
        n = front ? n : -n;
        if (dot(n, d) >= 0.0) {
            n = ngf;
        }

        if (mkind == MAT_EMISSIVE) {
            vec3 le = albedo_at(m, p_rest);
            if (depth_i == 0u) {
                depth = h.t;
                position = p_rest;
                visibility = 1.0;
            }
            if (feat_open) {
                albedo = feat_tint * emission_feature(le);
                normal = n;
                feat_open = false;
            }
            bool emits = front || (floatBitsToUint(prims[4u * prim].w) & 3u) == KIND_TRIANGLE;
            if (emits) {
                float w = 1.0;
                if (prev_bsdf_pdf > 0.0 && prims[4u * prim + 2u].w > 0.0) {
                    // o is still the previous vertex's origin.
                    float pdf_light = light_pdf(prim, o, h.t * h.t, abs(dot(ng, d)), time);
                    w = power_heuristic(prev_bsdf_pdf, pdf_light);
                }
                color += beta * w * le;
            }
            break;
        }

        vec3 alb = albedo_at(m, p_rest);
        vec4 m0 = mats[3u * m];
        uint cls = floatBitsToUint(m0.x) & 255u;
        float alpha = m0.z;
        float ior = m0.w;
        // Delta lobes (mirror, smooth or rough glass) get no next-event
        // estimation; dielectrics are sampled by their BSDF only.
        bool delta = cls == MAT_DIELECTRIC || (cls == MAT_CONDUCTOR && alpha < 1e-3);
        if (depth_i == 0u) {
            albedo = alb;
            normal = n;
            depth = h.t;
            position = p_rest;
            visibility = 1.0;
        }
        // RENDER-FEATURES: a smooth mirror passes the albedo and normal
        // features on to what it shows, times its reflectance (glass keeps
        // its own: its sampled lobe, reflection or refraction, would make
        // the features noisy).
        bool mirror = cls == MAT_CONDUCTOR && alpha < 1e-3;
        if (feat_open && !mirror) {
            albedo = feat_tint * alb;
            normal = n;
            feat_open = false;
        }
        if (depth_i == max_depth) {
            break;
        }
        vec3 po = offset_origin(p, ngf);
        uint dim = DIM_VERTEX + 4u * depth_i;

        vec3 wo = -d;
        // Next-event estimation (for the features: the visibility's shadow
        // ray, at the first vertex only).
#ifdef FEATURES_ONLY
        if (P.counts.w > 0u && !delta && depth_i == 0u) {
#else
        if (P.counts.w > 0u && !delta) {
#endif
            vec3 lp, ln;
            uint lprim;
            sample_light(rand2(key, dim), rand2(key, dim + 1u), po, time, lp, ln, lprim);
            vec3 to = lp - po;
            float dist2 = dot(to, to);
            float dist = sqrt(dist2);
            vec3 wi = to / dist;
            float cos_s = dot(n, wi);
            float cos_l = -dot(ln, wi);
            bool unoccluded = false;
            if (cos_s > 0.0 && cos_l > 0.0) {
                Hit s = trace(po, wi, time, 0.0, dist * (1.0 - 1e-4), true);
                unoccluded = s.prim < 0;
                if (unoccluded) {
                    uint lm = prim_material(lprim);
                    vec3 le = albedo_at(lm, rest_position(lprim, lp - time * prims[4u * lprim + 3u].xyz));
                    float pdf_light = light_pdf(lprim, po, dist2, cos_l, time);
                    float pdf_bsdf;
                    vec3 fc = bsdf_eval(cls, alb, alpha, ior, n, wo, wi, pdf_bsdf);
                    float w = power_heuristic(pdf_light, pdf_bsdf);
                    color += beta * fc * le * (w / pdf_light);
                }
            }
            if (depth_i == 0u) {
                visibility = unoccluded ? 1.0 : 0.0;
            }
        }
#ifdef FEATURES_ONLY
        if (!feat_open) {
            break;
        }
#endif

        // BSDF sampling.
        vec2 u = rand2(key, dim + 2u);
        vec2 u_rr = rand2(key, dim + 3u);   // .x roulette, .y lobe choice
        vec3 wi;
        vec3 weight;
        float pdf = 0.0;
        if (cls == MAT_DIELECTRIC) {
            // eta = η_t/η_i across the surface in the direction of travel.
            float eta = front ? ior : 1.0 / ior;
            float co = dot(n, wo);
            vec3 tint = mats[3u * m + 1u].xyz;
            if (abs(ior - 1.0) < 1e-4) {
                wi = d;   // index-matched: the surface is invisible
                weight = tint;
            } else {
                vec3 h = alpha < 1e-3 ? n : ggx_sample_h(n, wo, alpha, u);
                float f = fresnel_dielectric(dot(wo, h), eta);
                if (u_rr.y < f) {
                    wi = reflect(-wo, h);
                    weight = vec3(1.0);
                } else {
                    wi = refract(-wo, h, 1.0 / eta);
                    weight = tint;
                }
                if (alpha >= 1e-3) {
                    weight *= ggx_g1(abs(dot(n, wi)), alpha);
                }
                // A reflection must leave on wo's side, a refraction on the other.
                bool reflected = u_rr.y < f;
                if (dot(wi, wi) == 0.0 || (dot(n, wi) > 0.0) != reflected || co <= 0.0) {
                    break;
                }
            }
        } else if (cls == MAT_CONDUCTOR && alpha < 1e-3) {
            wi = reflect(-wo, n);
            weight = schlick(alb, dot(n, wo));
        } else if (cls == MAT_DIFFUSE) {
            wi = cosine_hemisphere(n, u);
            weight = alb;
            pdf = max(dot(n, wi), 0.0) / PI;
        } else {
            bool spec = cls == MAT_CONDUCTOR || u_rr.y < plastic_spec_prob(dot(n, wo), ior, alb);
            wi = spec ? reflect(-wo, ggx_sample_h(n, wo, alpha, u)) : cosine_hemisphere(n, u);
            vec3 fc = bsdf_eval(cls, alb, alpha, ior, n, wo, wi, pdf);
            weight = pdf > 0.0 ? fc / pdf : vec3(0.0);
        }
        float cos_s = dot(n, wi);
        if ((!delta && (cos_s <= 0.0 || pdf <= 0.0)) || all(equal(weight, vec3(0.0)))) {
            break;
        }
        prev_bsdf_pdf = delta ? 0.0 : pdf;
        beta *= weight;
        if (feat_open) {
            feat_tint *= weight;
        }
        o = offset_origin(p, dot(ngf, wi) > 0.0 ? ngf : -ngf);
        d = normalize(wi);

        if (depth_i >= 2u) {
            float q = min(max(beta.r, max(beta.g, beta.b)), 1.0);
            if (rand2(key, dim + 3u).x >= q) {
                break;
            }
            beta /= q;
        }
    }
    if (any(isnan(color)) || any(isinf(color))) {
        color = vec3(0.0);
    }
}

// Adds v to the 64-bit counter in words (lo, lo + 1).
void add_wide(uint lo, uint v)
{
    uint old = atomicAdd(work[lo], v);
    if (old > 0xffffffffu - v) {
        atomicAdd(work[lo + 1u], 1u);
    }
}
