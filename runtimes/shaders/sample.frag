#version 300 es
// The sample.  Diffuse part: the reflectance factor measured at the geometry seen at this
// pixel (linear interpolation in aspecular angle between the measured geometries, columns
// of u_sample_reflectance sorted by angle) times the band irradiance / π.  Specular part:
// GGX highlights of the emitters (tubes as line lights of finite width, panels and lamp
// bulbs as area lights) by linearly transformed cosines (Heitz et al. 2016), with the
// project's own fitted tables (runtimes/ltc.py) and Schlick's Fresnel.
// SHADE_TO_DISPLAY: as in booth.frag (0: four RGBA32F targets; 1: 8-bit display colour).
// COATING 1 (a sample with effect_coating): the flop BRDF fitted to the measured geometries
// (lbscene.engine.coatings.flop: diffuse base + Cook-Torrance lobes under a clear coat) lit by
// each emitter integrated over its extent (EMITTER_SEGMENTS points along a tube, a grid over a
// panel), and, with flakes, sparkle (Poisson counts of glinting flakes per sample-space cell,
// from a stable hash) and graininess (the diffuse part modulated per cell): see
// docs "Effect coatings" and lbscene.runtimes.coating.
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef SHADE_TO_DISPLAY
#define SHADE_TO_DISPLAY 0
#endif
#ifndef COATING
#define COATING 0
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
uniform sampler2D u_emitters;            // (24 × emitters), layout in runtimes/graph.py
uniform int u_emitter_count;
uniform sampler2D u_ltc_minv;            // (size × size): x = sqrt(1 − cos θv), y = roughness
uniform sampler2D u_ltc_mag;
uniform int u_ltc_size;
uniform float u_roughness;
uniform float u_specular_weight;
uniform float u_f0;
#if COATING
uniform sampler2D u_coating;             // row 0 diffuse a, rows 1..3 lobes s_k, row 4 flake ρ_f;
                                         // texel x = band block
uniform int u_coating_lobes;
uniform vec3 u_coating_alphas;
uniform int u_coating_beckmann;          // 1: Beckmann lobes, 0: GGX
uniform float u_coat_n;
uniform float u_coat_diffuse_t;          // the coat's transmittance for diffuse light
uniform vec2 u_sample_size_mm;
uniform int u_flakes;                    // 0: flop only
uniform float u_flake_density_per_mm2;
uniform float u_flake_area_mm2;          // mean flake area × mean visible share
uniform float u_flake_alpha;             // Beckmann α of the flake normals
uniform float u_flake_cell_mm;
uniform float u_grain_sigma;             // relative std of the diffuse part per cell
uniform float u_glint_bin;               // slope-space bin of the half vector
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

// ∫ over the great arc a→b of the edge term of Lambert's formula (z component).
float edge_integral(vec3 a, vec3 b) {
    vec3 c = cross(a, b);
    float s = length(c);
    return s > 1e-7 ? c.z * atan(s, dot(a, b)) / s : 0.0;
}

// Integral of the clamped cosine over the quad transformed by minv (quad given relative
// to the shading point, wound counter-clockwise as seen from it; the back side gives 0).
float ltc_quad(mat3 minv, vec3 q0, vec3 q1, vec3 q2, vec3 q3) {
    vec3 p[4] = vec3[4](minv * q0, minv * q1, minv * q2, minv * q3);
    vec3 c[6];
    int n = 0;
    for (int i = 0; i < 4; i++) {
        vec3 a = p[i];
        vec3 b = p[(i + 1) & 3];
        if (a.z >= 0.0) {
            c[n] = a;
            n++;
        }
        if ((a.z >= 0.0) != (b.z >= 0.0)) {
            c[n] = mix(a, b, a.z / (a.z - b.z));
            n++;
        }
    }
    if (n < 3) {
        return 0.0;
    }
    float sum = 0.0;
    for (int i = 0; i < n; i++) {
        sum += edge_integral(normalize(c[i]), normalize(c[i + 1 < n ? i + 1 : 0]));
    }
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

// GGX highlights of every emitter (LTC), added to the four band blocks.
void specular(vec3 P, vec3 N, vec3 V, inout vec4 l0, inout vec4 l1, inout vec4 l2, inout vec4 l3) {
    float cos_v = clamp(dot(N, V), 1e-4, 1.0);
    vec4 t1 = ltc_fetch(u_ltc_minv, u_roughness, cos_v);
    vec4 t2 = ltc_fetch(u_ltc_mag, u_roughness, cos_v);
    mat3 minv = mat3(vec3(t1.x, 0.0, t1.y), vec3(0.0, 1.0, 0.0), vec3(t1.z, 0.0, t1.w));
    vec3 T1 = V - N * dot(V, N);
    T1 = length(T1) > 1e-5 ? normalize(T1)
                           : normalize(cross(N, abs(N.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
    vec3 T2 = cross(N, T1);
    minv = minv * transpose(mat3(T1, T2, N));
    float lobe = (u_f0 * t2.x + (1.0 - u_f0) * t2.y) * u_specular_weight;

    vec4 s0 = vec4(0.0), s1 = vec4(0.0), s2 = vec4(0.0), s3 = vec4(0.0);
    for (int e = 0; e < u_emitter_count; e++) {
        vec4 e0 = emitter_texel(e, 0);
        vec4 e1 = emitter_texel(e, 1);
        vec4 e2 = emitter_texel(e, 2);
        vec3 c = e0.xyz;
        int kind = int(e0.w + 0.5);
        vec3 w = normalize(P - c);            // emitter → shading point
        float hl = e1.w;
        float hw = e2.w;
        vec3 a;
        vec3 s;
        float area_mm2;
        if (kind == 1) {                      // tube: a quad along the axis facing P
            s = cross(w, e1.xyz);
            float sl = length(s);
            if (sl < 1e-4) {
                continue;
            }
            a = e1.xyz * hl;
            s = s / sl * hw;
            // Lambertian cylinder: I = I_ref·sin θ over a projected area 2rℓ·sin θ, so its
            // radiance is I_ref / 2rℓ in every direction (engine/emitters.py)
            area_mm2 = 4.0 * hl * hw;
        } else if (kind == 2) {               // panel, emitting toward aim
            float ca = dot(w, e2.xyz);
            if (ca <= 0.0) {
                continue;
            }
            a = e1.xyz * hl;
            s = emitter_texel(e, 3).xyz * hw;
            area_mm2 = 4.0 * hl * hw;         // Lambertian rectangle: radiance I_ref / A
        } else {                              // sphere: a facing square of area π r²
            vec3 ax = normalize(cross(w, abs(w.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
            a = ax * hw;
            s = cross(w, ax) * hw;
            area_mm2 = 4.0 * hw * hw;
        }
        vec3 q = c - P;
        float form = ltc_quad(minv, q - a - s, q + a - s, q + a + s, q - a + s);
        if (form <= 0.0) {
            continue;
        }
        // emitter radiance toward P: its own radiance I_ref / A times the profile's modulation
        // (W·sr⁻¹·m⁻²·nm⁻¹)
        float theta = acos(clamp(dot(w, e2.xyz), -1.0, 1.0));
        float k = form * emitter_profile(e, theta) / (area_mm2 * 1e-6);
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

#if COATING
// ---------------------------------------------------------------- effect coating

const int EMITTER_SEGMENTS = 8;

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

float fresnel_t(float cos_i, float n) {
    float ci = clamp(cos_i, 0.0, 1.0);
    float ct = sqrt(max(1.0 - (1.0 - ci * ci) / (n * n), 0.0));
    float rs = (ci - n * ct) / max(ci + n * ct, 1e-12);
    float rp = (n * ci - ct) / max(n * ci + ct, 1e-12);
    return 1.0 - 0.5 * (rs * rs + rp * rp);
}

// a direction above the sample (unit, world) → the direction inside the coat that leaves along it
vec3 into_coat(vec3 d, vec3 N, float n) {
    vec3 t = (d - N * dot(d, N)) / n;
    return t + N * sqrt(max(1.0 - dot(t, t), 0.0));
}

float lobe_d(float c, float a) {
    float c2 = max(c * c, 1e-9);
    float a2 = a * a;
    if (u_coating_beckmann == 1) {
        return exp(-(1.0 - c2) / (c2 * a2)) / (PI * a2 * c2 * c2);
    }
    float d = c2 * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

// per-flake density of normals (Beckmann, sr⁻¹): D_B(m) cos θ_m
float flake_pdf(float c) {
    float c2 = max(c * c, 1e-9);
    float a2 = u_flake_alpha * u_flake_alpha;
    return exp(-(1.0 - c2) / (c2 * a2)) / (PI * a2 * c2 * max(c, 1e-5));
}

vec4 coat_row(int row, int block) {
    return texelFetch(u_coating, ivec2(block, row), 0);
}

// One lamp element seen from P: direction l (unit), solid angle dω (sr) and radiance L (four band
// blocks, W·sr⁻¹·m⁻²·nm⁻¹).  Adds the flop lobes (with glints) to lo*, and the element's
// irradiance to e* (all of it) and et* (times the coat's transmittance T(θ_l)).
void coat_element(vec3 N, vec3 V, vec3 Vc, float cv, float tv, vec3 T1, vec3 T2, ivec3 cell,
                  float cell_mm, int element, vec3 l, float domega, vec4 L0, vec4 L1, vec4 L2, vec4 L3,
                  inout vec4 lo0, inout vec4 lo1, inout vec4 lo2, inout vec4 lo3,
                  inout vec4 e0, inout vec4 e1, inout vec4 e2, inout vec4 e3,
                  inout vec4 et0, inout vec4 et1, inout vec4 et2, inout vec4 et3) {
    float cl = dot(l, N);
    if (cl <= 0.0 || domega <= 0.0) {
        return;
    }
    float n = u_coat_n;
    float tl = fresnel_t(cl, n);
    float g = cl * domega;
    e0 += L0 * g; e1 += L1 * g; e2 += L2 * g; e3 += L3 * g;
    et0 += L0 * (g * tl); et1 += L1 * (g * tl); et2 += L2 * (g * tl); et3 += L3 * (g * tl);
    vec3 lc = into_coat(l, N, n);
    float clc = max(dot(lc, N), 1e-4);
    vec3 h = normalize(lc + Vc);
    float ch = dot(h, N);
    // the lobes: (T T / n²) Σ s_k D_k(h') / (4 cos θ_l' cos θ_v'), times L cos θ_l dω
    float k0 = tl * tv / (n * n) / (4.0 * clc * cv) * g;
    vec4 s0 = vec4(0.0), s1 = vec4(0.0), s2 = vec4(0.0), s3 = vec4(0.0);
    for (int j = 0; j < 3; j++) {
        if (j >= u_coating_lobes) {
            break;
        }
        float d = lobe_d(ch, u_coating_alphas[j]) * k0;
        s0 += d * coat_row(1 + j, 0); s1 += d * coat_row(1 + j, 1);
        s2 += d * coat_row(1 + j, 2); s3 += d * coat_row(1 + j, 3);
    }
    vec4 b0 = s0 * L0, b1 = s1 * L1, b2 = s2 * L2, b3 = s3 * L3;
    if (u_flakes == 1) {
        // expected glinting flakes in the cell: N_cell · p(h') · dω_h',
        // dω_h' = dω cos θ_l / (n² cos θ_l') / (4 l'·h')
        float cell_area = cell_mm * cell_mm;
        float domega_h = domega * cl / (n * n * clc) / (4.0 * max(dot(lc, h), 1e-4));
        float lam = u_flake_density_per_mm2 * cell_area * flake_pdf(ch) * domega_h;
        if (lam > 1e-7) {
            // which flakes: the cell, the half vector's slope-space bin (in the sample's frame), the
            // lamp element
            vec2 slope = -vec2(dot(h, T1), dot(h, T2)) / max(ch, 1e-3);
            ivec2 bin = ivec2(floor(slope / u_glint_bin));
            float u = hash_unit(ivec4(cell.x, cell.y, (bin.x * 7919 + bin.y) * 8 + cell.z, element));
            float k = poisson_inverse(u, lam);
            // one glint: ρ_f T T L over the flake's share of the cell seen along v: a (h'·v')/(cos θ_v' A)
            float unit = tl * tv * u_flake_area_mm2 * dot(h, Vc) / (cv * cell_area);
            float f = k / lam - 1.0;
            b0 += min(lam * unit * coat_row(4, 0) * L0, b0) * f;
            b1 += min(lam * unit * coat_row(4, 1) * L1, b1) * f;
            b2 += min(lam * unit * coat_row(4, 2) * L2, b2) * f;
            b3 += min(lam * unit * coat_row(4, 3) * L3, b3) * f;
        }
    }
    lo0 += b0; lo1 += b1; lo2 += b2; lo3 += b3;
}

// The coating's radiance at P: lamps integrated over their extent for the lobes, the vertex
// irradiance for the diffuse base.
void coating(vec3 P, vec3 N, vec3 V, out vec4 l0, out vec4 l1, out vec4 l2, out vec4 l3) {
    float n = u_coat_n;
    vec3 Vc = into_coat(V, N, n);
    float cv = max(dot(Vc, N), 1e-4);
    float tv = fresnel_t(dot(V, N), n);
    // the sample's frame (slopes of the half vector, flake cells): from its uv
    vec3 dpx = dFdx(P), dpy = dFdy(P);
    vec2 dux = dFdx(v_uv), duy = dFdy(v_uv);
    vec3 T1 = dpx * duy.y - dpy * dux.y;
    T1 = length(T1) > 1e-12 ? normalize(T1 - N * dot(T1, N)) : normalize(cross(N, vec3(0.0, 1.0, 0.0)));
    vec3 T2 = cross(N, T1);
    vec2 s_mm = v_uv * u_sample_size_mm;
    // the view's cell, or a power-of-two multiple of it where a pixel covers more of the sample
    // (a smaller viewport): each pixel then draws the flakes of its whole footprint
    vec2 sx = dFdx(s_mm), sy = dFdy(s_mm);
    float footprint = sqrt(abs(sx.x * sy.y - sx.y * sy.x));
    float cell_mm = u_flake_cell_mm * exp2(max(0.0, ceil(log2(max(footprint, 1e-9) / u_flake_cell_mm) - 0.5)));
    ivec2 cell = ivec2(floor(s_mm / cell_mm));
    ivec3 cell3 = ivec3(cell, int(log2(cell_mm / u_flake_cell_mm) + 0.5));

    vec4 lo0 = vec4(0.0), lo1 = vec4(0.0), lo2 = vec4(0.0), lo3 = vec4(0.0);
    vec4 e0 = vec4(0.0), e1 = vec4(0.0), e2 = vec4(0.0), e3 = vec4(0.0);
    vec4 et0 = vec4(0.0), et1 = vec4(0.0), et2 = vec4(0.0), et3 = vec4(0.0);
    for (int e = 0; e < u_emitter_count; e++) {
        vec4 t0 = emitter_texel(e, 0);
        vec4 t1 = emitter_texel(e, 1);
        vec4 t2 = emitter_texel(e, 2);
        vec3 c = t0.xyz;
        int kind = int(t0.w + 0.5);
        float hl = t1.w, hw = t2.w;
        vec4 I0 = emitter_texel(e, 4), I1 = emitter_texel(e, 5), I2 = emitter_texel(e, 6), I3 = emitter_texel(e, 7);
        if (kind == 1) {                          // tube: segments along its axis
            float seg = 2.0 * hl / float(EMITTER_SEGMENTS);
            for (int i = 0; i < EMITTER_SEGMENTS; i++) {
                vec3 q = c + t1.xyz * (hl * (2.0 * (float(i) + 0.5) / float(EMITTER_SEGMENTS) - 1.0));
                vec3 d = q - P;
                float r = length(d);
                vec3 l = d / r;
                float sin_ax = length(cross(l, t1.xyz));
                // Lambertian cylinder: radiance I_ref / (2 r ℓ), seen across 2 r seg sin θ_axis
                float domega = 2.0 * hw * seg * sin_ax / (r * r);
                float rad = emitter_profile(e, acos(clamp(dot(-l, t2.xyz), -1.0, 1.0)))
                            / (4.0 * hl * hw * 1e-6);
                coat_element(N, V, Vc, cv, tv, T1, T2, cell3, cell_mm, e * 64 + i, l, domega, I0 * rad, I1 * rad,
                             I2 * rad, I3 * rad, lo0, lo1, lo2, lo3, e0, e1, e2, e3, et0, et1, et2, et3);
            }
        } else if (kind == 2) {                   // panel: a 4 × 2 grid of cells
            vec3 w = emitter_texel(e, 3).xyz;
            for (int i = 0; i < 4; i++) {
                for (int j = 0; j < 2; j++) {
                    vec3 q = c + t1.xyz * (hl * ((float(i) + 0.5) / 2.0 - 1.0))
                               + w * (hw * ((float(j) + 0.5) - 1.0));
                    vec3 d = q - P;
                    float r = length(d);
                    vec3 l = d / r;
                    float ce = dot(-l, t2.xyz);
                    if (ce <= 0.0) {
                        continue;
                    }
                    float domega = (4.0 * hl * hw / 8.0) * ce / (r * r);
                    float rad = emitter_profile(e, acos(clamp(ce, -1.0, 1.0))) / (4.0 * hl * hw * 1e-6);
                    coat_element(N, V, Vc, cv, tv, T1, T2, cell3, cell_mm, e * 64 + 2 * i + j, l, domega, I0 * rad,
                                 I1 * rad, I2 * rad, I3 * rad, lo0, lo1, lo2, lo3, e0, e1, e2, e3,
                                 et0, et1, et2, et3);
                }
            }
        } else {                                  // sphere: one element of area π r² (= 4 hw²)
            vec3 d = c - P;
            float r = length(d);
            vec3 l = d / r;
            float domega = 4.0 * hw * hw / (r * r);
            float rad = emitter_profile(e, acos(clamp(dot(-l, t2.xyz), -1.0, 1.0))) / (4.0 * hw * hw * 1e-6);
            coat_element(N, V, Vc, cv, tv, T1, T2, cell3, cell_mm, e * 64, l, domega, I0 * rad, I1 * rad, I2 * rad,
                         I3 * rad, lo0, lo1, lo2, lo3, e0, e1, e2, e3, et0, et1, et2, et3);
        }
    }
    // diffuse base a T(θ_v)/(π n²): the lamps' own light with their T(θ_l), the rest of the vertex
    // irradiance (inter-reflected light, lamps hidden from the estimate) with the diffuse T̄
    float kd = tv / (PI * n * n);
    float grain = 1.0;
    if (u_flakes == 1 && u_grain_sigma > 0.0) {
        float ua = hash_unit(ivec4(cell, 104729 + cell3.z, 1));
        float ub = hash_unit(ivec4(cell, 104729 + cell3.z, 2));
        // σ per cell falls as 1/side (independent flakes): u_grain_sigma is the view's cell's
        float sg = u_grain_sigma * u_flake_cell_mm / cell_mm;
        grain = max(0.0, 1.0 + sg * sqrt(-2.0 * log(ua)) * cos(6.283185307179586 * ub));
    }
    kd *= grain;
    l0 = lo0 + coat_row(0, 0) * kd * (et0 + u_coat_diffuse_t * max(v_irradiance0 - e0, 0.0));
    l1 = lo1 + coat_row(0, 1) * kd * (et1 + u_coat_diffuse_t * max(v_irradiance1 - e1, 0.0));
    l2 = lo2 + coat_row(0, 2) * kd * (et2 + u_coat_diffuse_t * max(v_irradiance2 - e2, 0.0));
    l3 = lo3 + coat_row(0, 3) * kd * (et3 + u_coat_diffuse_t * max(v_irradiance3 - e3, 0.0));
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
    coating(P, N, V, l0, l1, l2, l3);
#else
    vec4 r0, r1, r2, r3;
    reflectance_at(aspecular_deg(P, N, V), r0, r1, r2, r3);
    vec4 l0 = r0 * v_irradiance0 * INV_PI;
    vec4 l1 = r1 * v_irradiance1 * INV_PI;
    vec4 l2 = r2 * v_irradiance2 * INV_PI;
    vec4 l3 = r3 * v_irradiance3 * INV_PI;
#endif
    if (u_specular_weight > 0.0 && u_emitter_count > 0) {
        specular(P, N, V, l0, l1, l2, l3);
    }
#if SHADE_TO_DISPLAY
    o_rgba = vec4(dither8(display_drive(spectral_to_xyz(l0, l1, l2, l3)).rgb, ivec2(gl_FragCoord.xy)), 1.0);
#else
    o_radiance0 = l0;
    o_radiance1 = l1;
    o_radiance2 = l2;
    o_radiance3 = l3;
#endif
}
