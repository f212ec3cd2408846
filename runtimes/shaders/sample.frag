#version 300 es
// The sample.  Diffuse part: the reflectance factor measured at the geometry seen at this
// pixel (linear interpolation in aspecular angle between the measured geometries, columns
// of u_sample_reflectance sorted by angle) times the band irradiance / π.  Specular part:
// GGX highlights of the emitters (tubes as line lights of finite width, panels and lamp
// bulbs as area lights) by linearly transformed cosines (Heitz et al. 2016), with the
// project's own fitted tables (runtimes/ltc.py) and Schlick's Fresnel.
// SHADE_TO_DISPLAY: as in booth.frag (0: four RGBA32F targets; 1: 8-bit display colour; the
// highlights are then summed in XYZ, from each emitter's XYZ the CPU computed, instead of in 16
// bands: the same sum, since spectral → XYZ is linear).
// EMITTER_KINDS (bits: 1 sphere, 2 tube, 4 panel) and EMITTER_PROFILES (0: every emitter's
// angular profile is flat) are the view's emitters (values view.emitter_kinds and
// view.emitter_profiles): the code of absent kinds and of flat profiles is left out (a CPU
// rasteriser runs every side of a branch that its lanes do not skip together).
// COATING 1 (a sample with effect_coating): the radiance the vertex stage computed from the flop
// BRDF fitted to the measured geometries with every lamp integrated over its extent
// (lib_coating.glsl, surface.vert), and, with flakes, sparkle (Poisson counts of glinting flakes
// per sample-space cell, from a stable hash) and graininess (the diffuse part modulated per cell):
// see docs "Effect coatings" and lbscene.runtimes.coating.
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef SHADE_TO_DISPLAY
#define SHADE_TO_DISPLAY 0
#endif
#ifndef COATING
#define COATING 0
#endif
#ifndef EMITTER_KINDS
#define EMITTER_KINDS 7
#endif
#ifndef EMITTER_PROFILES
#define EMITTER_PROFILES 1
#endif

in vec3 v_position_mm;
in vec3 v_normal;
in vec2 v_uv;
flat in int v_material;
in vec4 v_irradiance0;
in vec4 v_irradiance1;
in vec4 v_irradiance2;
in vec4 v_irradiance3;

uniform sampler2D u_sample_reflectance;  // (geometries × 5): rows 0..3 band blocks, row 4 x = aspecular deg
uniform int u_sample_geometry_count;
uniform vec3 u_eye_mm;
uniform vec3 u_illumination_mm;          // light that defines the measurement geometry
uniform sampler2D u_emitters;            // (25 × emitters), layout in runtimes/graph.py
uniform int u_emitter_count;
uniform sampler2D u_ltc_minv;            // (size × size): x = sqrt(1 − cos θv), y = roughness
uniform sampler2D u_ltc_mag;
uniform int u_ltc_size;
uniform float u_roughness;
uniform float u_specular_weight;
uniform float u_f0;
#if COATING
in vec4 v_glint0;                        // per emitter (surface.vert, lib_coating.glsl): λ per view
in vec4 v_glint1;                        // cell, one glint's radiance factor, half-vector slope
in vec4 v_glint2;
in vec4 v_glint3;
in float v_diffuse_share;                // the diffuse base's share of the smooth radiance
uniform vec2 u_sample_size_mm;
uniform int u_flakes;                    // 0: flop only
uniform float u_flake_cell_mm;
uniform float u_grain_sigma;             // relative std of the diffuse part per cell
uniform float u_glint_bin;               // slope-space bin of the half vector
uniform vec4 u_glint_spectrum[4];        // ρ_f × the emitters' mean band intensity
#endif

#if SHADE_TO_DISPLAY
layout(location = 0) out vec4 o_rgba;
#else
layout(location = 0) out vec4 o_radiance0;
layout(location = 1) out vec4 o_radiance1;
layout(location = 2) out vec4 o_radiance2;
layout(location = 3) out vec4 o_radiance3;
#endif

const float PI = 3.141592653589793;
const float INV_PI = 0.31830988618379067;
const int PROFILE_LAST = 63;            // PROFILE_SAMPLES - 1
const int PROFILE_TEXEL = 8;
const int XYZ_TEXEL = 24;               // the emitter's band intensities in XYZ (SHADE_TO_DISPLAY)
// (integer / and % are avoided: CPUs do not vectorise integer division)

// ---------------------------------------------------------------- measured geometries

float aspecular_deg(vec3 P, vec3 N, vec3 V) {
    vec3 L = normalize(u_illumination_mm - P);
    vec3 T = L - N * dot(L, N);
    float tl = length(T);
    T = tl > 1e-6 ? T / tl : normalize(cross(N, vec3(1.0, 0.0, 0.0)));
    float theta_i = acos(clamp(dot(L, N), -1.0, 1.0));
    float theta_v = atan(-dot(V, T), dot(V, N));   // > 0 on the far side from the light
    return degrees(theta_i - theta_v);
}

void reflectance_at(float asp, out vec4 r0, out vec4 r1, out vec4 r2, out vec4 r3) {
    int n = u_sample_geometry_count;
    if (n < 2) {
        r0 = texelFetch(u_sample_reflectance, ivec2(0, 0), 0);
        r1 = texelFetch(u_sample_reflectance, ivec2(0, 1), 0);
        r2 = texelFetch(u_sample_reflectance, ivec2(0, 2), 0);
        r3 = texelFetch(u_sample_reflectance, ivec2(0, 3), 0);
        return;
    }
    int i0 = 0;
    int i1 = 0;
    float t = 0.0;
    float prev = texelFetch(u_sample_reflectance, ivec2(0, 4), 0).x;
    if (asp > prev && n > 1) {
        i0 = n - 1;
        i1 = n - 1;
        for (int k = 1; k < n; k++) {
            float a = texelFetch(u_sample_reflectance, ivec2(k, 4), 0).x;
            if (asp <= a) {
                i0 = k - 1;
                i1 = k;
                t = (asp - prev) / max(a - prev, 1e-6);
                break;
            }
            prev = a;
        }
    }
    r0 = mix(texelFetch(u_sample_reflectance, ivec2(i0, 0), 0), texelFetch(u_sample_reflectance, ivec2(i1, 0), 0), t);
    r1 = mix(texelFetch(u_sample_reflectance, ivec2(i0, 1), 0), texelFetch(u_sample_reflectance, ivec2(i1, 1), 0), t);
    r2 = mix(texelFetch(u_sample_reflectance, ivec2(i0, 2), 0), texelFetch(u_sample_reflectance, ivec2(i1, 2), 0), t);
    r3 = mix(texelFetch(u_sample_reflectance, ivec2(i0, 3), 0), texelFetch(u_sample_reflectance, ivec2(i1, 3), 0), t);
}

// ---------------------------------------------------------------- LTC

// Bilinear lookup (float textures are not filterable everywhere: fetch and mix).
vec4 ltc_fetch(sampler2D table, float roughness, float cos_theta) {
    float s = float(u_ltc_size - 1);
    vec2 x = vec2(sqrt(clamp(1.0 - cos_theta, 0.0, 1.0)), clamp(roughness, 0.0, 1.0)) * s;
    ivec2 i = ivec2(min(floor(x), vec2(s - 1.0)));
    vec2 f = x - vec2(i);
    vec4 a = texelFetch(table, i, 0);
    vec4 b = texelFetch(table, i + ivec2(1, 0), 0);
    vec4 c = texelFetch(table, i + ivec2(0, 1), 0);
    vec4 d = texelFetch(table, i + ivec2(1, 1), 0);
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// ∫ over the great arc a→b (unit vectors) of the edge term of Lambert's formula (z component):
// (a × b)_z · θ/sin θ with cos θ = a·b.  θ/sin θ = acos(y)/√(1 − y²) is a rational function of
// y = |a·b| on [0, 1] (relative error < 1.4e-6, fitted by least squares; π/2 at y = 0, 1 at
// y = 1), and for a·b < 0, acos(−y) = π − acos(y) gives π/√(1 − y²) minus it: no atan, which
// CPU rasterisers evaluate as a long polynomial.
float edge_integral(vec3 a, vec3 b) {
    float x = dot(a, b);
    float y = abs(x);
    float r = (5.4516069 + (3.1335957 + 0.0895909 * y) * y) / (3.4706053 + (4.2041799 + y) * y);
    float theta_over_sin = x >= 0.0 ? r : PI * inversesqrt(max(1.0 - x * x, 1e-7)) - r;
    return cross(a, b).z * theta_over_sin;
}

// The part of the edge a→b above the horizon z = 0 (unit ends; its edge term, 0 when the edge
// is wholly below): an end below is moved to where the edge crosses the horizon, and that
// crossing is recorded as where the polygon's boundary leaves the upper half (a above) or
// comes back into it (b above).
float clipped_edge(vec3 a, vec3 b, bool a_up, bool b_up, inout vec3 leave, inout vec3 enter) {
    float dz = a.z - b.z;
    vec3 m = mix(a, b, a.z / (dz != 0.0 ? dz : 1.0));
    m *= inversesqrt(max(dot(m, m), 1e-30));
    leave = a_up && !b_up ? m : leave;
    enter = !a_up && b_up ? m : enter;
    float e = edge_integral(a_up ? a : m, b_up ? b : m);
    return a_up || b_up ? e : 0.0;
}

// Integral of the clamped cosine over the quad transformed by minv (the quad c ± a ± s relative
// to the shading point, wound counter-clockwise as seen from it; the back side gives 0).  The
// quad is clipped to the horizon without building the clipped polygon: each edge contributes
// its part above the horizon and the horizon arc from the crossing where the boundary leaves
// the upper half to the one where it comes back closes the polygon (a convex quad crosses the
// horizon twice or not at all; with no crossing that arc is between two zero vectors: 0).
// Branch-free, so SIMD lanes that straddle the horizon differently stay together.
float ltc_quad(mat3 minv, vec3 c, vec3 a, vec3 s) {
    c = minv * c;                             // the transform is linear: three products, not four
    a = minv * a;
    s = minv * s;
    vec3 p0 = normalize(c - a - s), p1 = normalize(c + a - s), p2 = normalize(c + a + s),
         p3 = normalize(c - a + s);
    bvec4 above = greaterThanEqual(vec4(p0.z, p1.z, p2.z, p3.z), vec4(0.0));
    if (!any(above)) {
        return 0.0;                           // wholly below the horizon
    }
    vec3 leave = vec3(0.0), enter = vec3(0.0);
    float sum = clipped_edge(p0, p1, above.x, above.y, leave, enter)
              + clipped_edge(p1, p2, above.y, above.z, leave, enter)
              + clipped_edge(p2, p3, above.z, above.w, leave, enter)
              + clipped_edge(p3, p0, above.w, above.x, leave, enter);
    sum += edge_integral(leave, enter);
    return max(-sum, 0.0) * (0.5 * INV_PI);
}

vec4 emitter_texel(int row, int k) {
    return texelFetch(u_emitters, ivec2(k, row), 0);
}

float emitter_profile(int row, float theta) {
    float x = clamp(theta * INV_PI, 0.0, 1.0) * float(PROFILE_LAST);
    int i = min(int(floor(x)), PROFILE_LAST - 1);
    int j = i + 1;
    float a = emitter_texel(row, PROFILE_TEXEL + (i >> 2))[i & 3];
    float b = emitter_texel(row, PROFILE_TEXEL + (j >> 2))[j & 3];
    return mix(a, b, x - float(i));
}

// The emitter's quad as LTC sees it from P (centre c, half extents a and s; w: emitter → P)
// and its area; false where it shows no emitting side.
bool tube_quad(vec3 w, vec4 e1, vec4 e2, out vec3 a, out vec3 s, out float area_mm2) {
    // a quad along the axis facing P.  Lambertian cylinder: I = I_ref·sin θ over a projected
    // area 2rℓ·sin θ, so its radiance is I_ref / 2rℓ in every direction (engine/light/emitters.py)
    s = cross(w, e1.xyz);
    float sl = length(s);
    a = e1.xyz * e1.w;
    s = s * (e2.w / max(sl, 1e-4));
    area_mm2 = 4.0 * e1.w * e2.w;
    return sl >= 1e-4;
}

bool panel_quad(int e, vec3 w, vec4 e1, vec4 e2, out vec3 a, out vec3 s, out float area_mm2) {
    // emitting toward aim; Lambertian rectangle: radiance I_ref / A
    a = e1.xyz * e1.w;
    s = emitter_texel(e, 3).xyz * e2.w;
    area_mm2 = 4.0 * e1.w * e2.w;
    return dot(w, e2.xyz) > 0.0;
}

bool sphere_quad(vec3 w, vec4 e2, out vec3 a, out vec3 s, out float area_mm2) {
    // a facing square of area π r²
    vec3 ax = normalize(cross(w, abs(w.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
    a = ax * e2.w;
    s = cross(w, ax) * e2.w;
    area_mm2 = 4.0 * e2.w * e2.w;
    return true;
}

// Emitter e's highlight at P per unit of its band intensities: the LTC integral of the lobe over
// its quad times its radiance per unit intensity toward P (the profile's modulation / area, m⁻²).
float emitter_highlight(int e, vec3 P, mat3 minv) {
    vec4 e0 = emitter_texel(e, 0);
    vec4 e1 = emitter_texel(e, 1);
    vec4 e2 = emitter_texel(e, 2);
    vec3 w = normalize(P - e0.xyz);          // emitter → shading point
    vec3 a, s;
    float area_mm2;
#if EMITTER_KINDS == 2
    bool seen = tube_quad(w, e1, e2, a, s, area_mm2);
#elif EMITTER_KINDS == 4
    bool seen = panel_quad(e, w, e1, e2, a, s, area_mm2);
#elif EMITTER_KINDS == 1
    bool seen = sphere_quad(w, e2, a, s, area_mm2);
#else
    bool seen;
    int kind = int(e0.w + 0.5);
    if (kind == 1) {
        seen = tube_quad(w, e1, e2, a, s, area_mm2);
    } else if (kind == 2) {
        seen = panel_quad(e, w, e1, e2, a, s, area_mm2);
    } else {
        seen = sphere_quad(w, e2, a, s, area_mm2);
    }
#endif
    if (!seen) {
        return 0.0;
    }
    float form = ltc_quad(minv, e0.xyz - P, a, s);
#if EMITTER_PROFILES
    float theta = acos(clamp(dot(w, e2.xyz), -1.0, 1.0));
    form *= emitter_profile(e, theta);
#endif
    return form / (area_mm2 * 1e-6);
}

// The LTC frame at P: minv (world → the lobe's cosine space) and the lobe's magnitude
// (Fresnel, the specular weight).
float ltc_frame(vec3 N, vec3 V, out mat3 minv) {
    float cos_v = clamp(dot(N, V), 1e-4, 1.0);
    vec4 t1 = ltc_fetch(u_ltc_minv, u_roughness, cos_v);
    vec4 t2 = ltc_fetch(u_ltc_mag, u_roughness, cos_v);
    minv = mat3(vec3(t1.x, 0.0, t1.y), vec3(0.0, 1.0, 0.0), vec3(t1.z, 0.0, t1.w));
    vec3 T1 = V - N * dot(V, N);
    T1 = length(T1) > 1e-5 ? normalize(T1)
                           : normalize(cross(N, abs(N.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
    vec3 T2 = cross(N, T1);
    minv = minv * transpose(mat3(T1, T2, N));
    return (u_f0 * t2.x + (1.0 - u_f0) * t2.y) * u_specular_weight;
}

#if SHADE_TO_DISPLAY
// GGX highlights of every emitter (LTC) in XYZ: Σ_e k_e · XYZ_e, with XYZ_e the emitter's band
// intensities taken to XYZ on the CPU (the view's band weights, as spectral_to_xyz).
vec3 specular_xyz(vec3 P, vec3 N, vec3 V) {
    mat3 minv;
    float lobe = ltc_frame(N, V, minv);
    vec3 xyz = vec3(0.0);
    for (int e = 0; e < u_emitter_count; e++) {
        xyz += emitter_highlight(e, P, minv) * emitter_texel(e, XYZ_TEXEL).xyz;
    }
    return lobe * xyz;
}
#else
// GGX highlights of every emitter (LTC), added to the four band blocks.
void specular(vec3 P, vec3 N, vec3 V, inout vec4 l0, inout vec4 l1, inout vec4 l2, inout vec4 l3) {
    mat3 minv;
    float lobe = ltc_frame(N, V, minv);
    vec4 s0 = vec4(0.0), s1 = vec4(0.0), s2 = vec4(0.0), s3 = vec4(0.0);
    for (int e = 0; e < u_emitter_count; e++) {
        float k = emitter_highlight(e, P, minv);
        s0 += k * emitter_texel(e, 4);
        s1 += k * emitter_texel(e, 5);
        s2 += k * emitter_texel(e, 6);
        s3 += k * emitter_texel(e, 7);
    }
    l0 += lobe * s0;
    l1 += lobe * s1;
    l2 += lobe * s2;
    l3 += lobe * s3;
}
#endif

#if COATING
// ---------------------------------------------------------------- effect coating

// Integer hash (PCG, O'Neill 2014 / Jarzynski & Olano 2020) → uniform in (0, 1).
uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float hash_unit(ivec4 k) {
    uint h = pcg_hash(uint(k.x) ^ pcg_hash(uint(k.y) ^ pcg_hash(uint(k.z) ^ pcg_hash(uint(k.w)))));
    return (float(h >> 8u) + 0.5) * (1.0 / 16777216.0);
}

// Poisson(λ) by the inverse CDF of one uniform: exact below λ = 16, a rounded normal above.
float poisson_inverse(float u, float lam) {
    if (lam > 16.0) {
        // normal quantile (Tukey's lambda approximation, |error| < 0.01σ)
        float z = 4.91 * (pow(u, 0.14) - pow(1.0 - u, 0.14));
        return max(0.0, floor(lam + sqrt(lam) * z + 0.5));
    }
    float p = exp(-lam);
    float c = p;
    float k = 0.0;
    for (int i = 0; i < 48; i++) {
        if (u <= c) {
            break;
        }
        k += 1.0;
        p *= lam / k;
        c += p;
    }
    return k;
}

// The glints of one emitter in the pixel's cell: g = (λ per view cell, one glint's radiance factor
// per view cell, half-vector slope); `a` = (cell / view cell)² rescales both to the pixel's cell.
float glints(vec4 g, ivec3 cell, int em, float a) {
    if (g.x * a < 1e-7) {
        return 0.0;
    }
    ivec2 bin = ivec2(floor(g.zw / u_glint_bin));
    float lam = g.x * a;
    float k = poisson_inverse(hash_unit(ivec4(cell.x, cell.y, (bin.x * 7919 + bin.y) * 8 + cell.z, em)), lam);
    return g.y / a * (k - lam);
}

// The coating at this pixel: the smooth part from the vertices (flop BRDF with the lamps
// integrated over their extent, lib_coating.glsl), then per flake cell of the sample the
// graininess of the diffuse part and the glints (Poisson counts from a stable hash of the cell,
// the half vector's slope bin and the emitter).
void coating(out vec4 l0, out vec4 l1, out vec4 l2, out vec4 l3) {
    l0 = v_irradiance0;
    l1 = v_irradiance1;
    l2 = v_irradiance2;
    l3 = v_irradiance3;
    if (u_flakes == 0) {
        return;
    }
    vec2 s_mm = v_uv * u_sample_size_mm;
    // the view's cell, or a power-of-two multiple of it where a pixel covers more of the sample
    // (a smaller viewport): each pixel then draws the flakes of its whole footprint
    vec2 sx = dFdx(s_mm), sy = dFdy(s_mm);
    float footprint = sqrt(abs(sx.x * sy.y - sx.y * sy.x));
    float level = max(0.0, ceil(log2(max(footprint, 1e-9) / u_flake_cell_mm) - 0.5));
    float cell_mm = u_flake_cell_mm * exp2(level);
    ivec3 cell = ivec3(ivec2(floor(s_mm / cell_mm)), int(level));
    float a = exp2(2.0 * level);
    float grain = 1.0;
    if (u_grain_sigma > 0.0) {
        float ua = hash_unit(ivec4(cell.xy, 104729 + cell.z, 1));
        float ub = hash_unit(ivec4(cell.xy, 104729 + cell.z, 2));
        // σ per cell falls as 1/side (independent flakes): u_grain_sigma is the view's cell's
        grain = max(0.0, 1.0 + u_grain_sigma / exp2(level) * sqrt(-2.0 * log(ua)) * cos(6.283185307179586 * ub));
    }
    float g = glints(v_glint0, cell, 0, a) + glints(v_glint1, cell, 1, a) + glints(v_glint2, cell, 2, a)
              + glints(v_glint3, cell, 3, a);
    float k = 1.0 + (grain - 1.0) * v_diffuse_share;
    l0 = max(l0 * k + u_glint_spectrum[0] * g, 0.0);
    l1 = max(l1 * k + u_glint_spectrum[1] * g, 0.0);
    l2 = max(l2 * k + u_glint_spectrum[2] * g, 0.0);
    l3 = max(l3 * k + u_glint_spectrum[3] * g, 0.0);
}
#endif

void main() {
    vec3 P = v_position_mm;
    vec3 N = normalize(v_normal);
    vec3 V = normalize(u_eye_mm - P);
    if (dot(N, V) < 0.0) {
        N = -N;
    }

#if COATING
    vec4 l0, l1, l2, l3;
    coating(l0, l1, l2, l3);
#else
    vec4 r0, r1, r2, r3;
    float asp = 0.0;
    if (u_sample_geometry_count > 1) {      // one measured geometry: no angle to interpolate in
        asp = aspecular_deg(P, N, V);
    }
    reflectance_at(asp, r0, r1, r2, r3);
    vec4 l0 = r0 * v_irradiance0 * INV_PI;
    vec4 l1 = r1 * v_irradiance1 * INV_PI;
    vec4 l2 = r2 * v_irradiance2 * INV_PI;
    vec4 l3 = r3 * v_irradiance3 * INV_PI;
#endif
#if SHADE_TO_DISPLAY
    vec3 xyz = spectral_to_xyz(l0, l1, l2, l3);
    if (u_specular_weight > 0.0 && u_emitter_count > 0) {
        xyz += specular_xyz(P, N, V);
    }
    o_rgba = vec4(dither8(display_drive(xyz).rgb, ivec2(gl_FragCoord.xy)), 1.0);
#else
    if (u_specular_weight > 0.0 && u_emitter_count > 0) {
        specular(P, N, V, l0, l1, l2, l3);
    }
    o_radiance0 = l0;
    o_radiance1 = l1;
    o_radiance2 = l2;
    o_radiance3 = l3;
#endif
}
