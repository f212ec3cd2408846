// lbscene shader library (a GLSL ES 3.00 chunk without #version): the effect coating's smooth part,
// evaluated in the vertex stage of the sample (surface.vert with COATING 1).
//
// The flop BRDF fitted to the measured geometries (lbscene.engine.coatings.flop: a diffuse base and
// K Cook-Torrance lobes under a clear coat of index n)
//     f = T(θ_l) T(θ_v) / n² · [a/π + Σ_k s_k D_k(h') / (4 cos θ_l' cos θ_v')]
// lit by every emitter integrated over its extent (EMITTER_SEGMENTS points along a tube, a 4 × 2
// grid on a panel, one element for a bulb), and, for the flakes, per emitter the expected number λ
// of glinting flakes per flake cell, the radiance factor of one glint and the slope of the mean
// half vector (the fragment stage draws the counts: sample.frag).  All of it varies slowly over
// the sample; the vertices of the sample's grid carry it and the rasteriser interpolates.
precision highp float;
precision highp int;
precision highp sampler2D;

#ifndef COATING
#define COATING 0
#endif

#if COATING
uniform sampler2D u_emitters;            // (24 × emitters), layout in runtimes/graph.py
uniform int u_emitter_count;
uniform vec3 u_eye_mm;
uniform vec4 u_coating_spectra[16];      // band blocks of: diffuse a, lobes s_1..s_3
uniform int u_coating_lobes;
uniform vec3 u_coating_alphas;
uniform int u_coating_beckmann;          // 1: Beckmann lobes, 0: GGX
uniform float u_coat_n;
uniform float u_coat_diffuse_t;          // the coat's transmittance for diffuse light
uniform int u_flakes;                    // 0: flop only
uniform float u_flake_density_per_mm2;
uniform float u_flake_area_mm2;          // mean flake area × mean visible share
uniform float u_flake_alpha;             // Beckmann α of the flake normals
uniform float u_flake_cell_mm;
uniform vec3 u_lobe_luminance;           // luminance-weighted lobe weights s_k
uniform float u_flake_luminance;         // luminance-weighted flake reflectance
uniform vec4 u_glint_spectrum[4];        // ρ_f × the emitters' mean band intensity Ī (W·sr⁻¹·nm⁻¹)
uniform float u_lamp_band_sum;           // Σ_b Ī_b

const float COAT_PI = 3.141592653589793;
const int EMITTER_SEGMENTS = 8;
const int COAT_PROFILE_LAST = 63;
const int COAT_PROFILE_TEXEL = 8;

vec4 coat_emitter(int row, int k) {
    return texelFetch(u_emitters, ivec2(k, row), 0);
}

float coat_profile(int row, float theta) {
    float x = clamp(theta / COAT_PI, 0.0, 1.0) * float(COAT_PROFILE_LAST);
    int i = min(int(floor(x)), COAT_PROFILE_LAST - 1);
    int j = i + 1;
    float a = coat_emitter(row, COAT_PROFILE_TEXEL + (i >> 2))[i & 3];
    float b = coat_emitter(row, COAT_PROFILE_TEXEL + (j >> 2))[j & 3];
    return mix(a, b, x - float(i));
}

float fresnel_t(float cos_i, float n) {
    float ci = clamp(cos_i, 0.0, 1.0);
    float ct = sqrt(max(1.0 - (1.0 - ci * ci) / (n * n), 0.0));
    float rs = (ci - n * ct) / max(ci + n * ct, 1e-12);
    float rp = (n * ci - ct) / max(n * ci + ct, 1e-12);
    return 1.0 - 0.5 * (rs * rs + rp * rp);
}

// a direction above the sample (unit) → the direction inside the coat that leaves along it
vec3 into_coat(vec3 d, vec3 N, float n) {
    vec3 t = (d - N * dot(d, N)) / n;
    return t + N * sqrt(max(1.0 - dot(t, t), 0.0));
}

float lobe_d(float c, float a) {
    float c2 = max(c * c, 1e-9);
    float a2 = a * a;
    if (u_coating_beckmann == 1) {
        return exp(-(1.0 - c2) / (c2 * a2)) / (COAT_PI * a2 * c2 * c2);
    }
    float d = c2 * (a2 - 1.0) + 1.0;
    return a2 / (COAT_PI * d * d);
}

// per-flake density of normals (Beckmann, sr⁻¹): D_B(m) cos θ_m
float flake_pdf(float c) {
    float c2 = max(c * c, 1e-9);
    float a2 = u_flake_alpha * u_flake_alpha;
    return exp(-(1.0 - c2) / (c2 * a2)) / (COAT_PI * a2 * c2 * max(c, 1e-5));
}

vec4 coat_row(int row, int block) {
    return u_coating_spectra[4 * row + block];
}

// One lamp element: direction l (unit), solid angle dω (sr), radiance `rad` × its emitter's bands.
// Scalars only (the spectra multiply once per emitter):
//   w.xyz  Σ rad cos θ_l dω (T T / n²) D_k(h') / (4 cos θ_l' cos θ_v')  (lobes k = 1..3)
//   w.w    Σ rad cos θ_l dω (T(θ_l) − T̄)         (the lamp's light on the base, beyond the T̄ the
//                                                  vertex irradiance gets)
//   gl     (λ, Σ λ·unit·share, Σ λ·slope(h') in the sample frame T1, T2): expected glints per cell,
//          their radiance factor, the λ-weighted slope of the half vector
void coat_element(vec3 N, vec3 T1, vec3 T2, vec3 Vc, float cv, float tv, vec3 l, float domega, float rad,
                  inout vec4 w, inout vec4 gl) {
    float cl = dot(l, N);
    if (cl <= 0.0 || domega <= 0.0) {
        return;
    }
    float n = u_coat_n;
    float tl = fresnel_t(cl, n);
    float gw = cl * domega * rad;
    vec3 lc = into_coat(l, N, n);
    float clc = max(dot(lc, N), 1e-4);
    vec3 h = normalize(lc + Vc);
    float ch = dot(h, N);
    float k0 = tl * tv / (n * n) / (4.0 * clc * cv) * gw;
    vec3 d = vec3(lobe_d(ch, u_coating_alphas.x), u_coating_lobes > 1 ? lobe_d(ch, u_coating_alphas.y) : 0.0,
                  u_coating_lobes > 2 ? lobe_d(ch, u_coating_alphas.z) : 0.0) * k0;
    w += vec4(d, gw * (tl - u_coat_diffuse_t));
    if (u_flakes == 1) {
        // expected glinting flakes per cell: N_cell · p(h') · dω_h',
        // dω_h' = dω cos θ_l / (n² cos θ_l') / (4 l'·h')
        float cell_area = u_flake_cell_mm * u_flake_cell_mm;
        float domega_h = domega * cl / (n * n * clc) / (4.0 * max(dot(lc, h), 1e-4));
        float lam = u_flake_density_per_mm2 * cell_area * flake_pdf(ch) * domega_h;
        // one glint: ρ_f T T L over its share of the cell seen along v, a (h'·v') / (cos θ_v' A); the
        // glints' mean (λ of them) is at most the flop's lobes here (luminance): the flop is the
        // measured mean, the glints its fluctuation
        float unit = tl * tv * u_flake_area_mm2 * dot(h, Vc) / (cv * cell_area) * rad;
        float mean = lam * unit * u_flake_luminance;
        float share = mean > 0.0 ? min(1.0, dot(d, u_lobe_luminance) / mean) : 0.0;
        gl += lam * vec4(1.0, unit * share, -dot(h, T1) / max(ch, 1e-3), -dot(h, T2) / max(ch, 1e-3));
    }
}

// The smooth part of the coating at P (radiance, four band blocks, into l0..l3, to which the
// diffuse base under the vertex irradiance e0..e3 is added), the diffuse part's luminance share,
// and per emitter (the first four) vec4(λ per cell of the view's cell size, one glint's radiance
// factor, the mean half vector's slope in the sample frame T1, T2).
void coating_vertex(vec3 P, vec3 N, vec3 T1, vec4 e0, vec4 e1, vec4 e2, vec4 e3,
                    out vec4 l0, out vec4 l1, out vec4 l2, out vec4 l3, out float diffuse_share,
                    out vec4 g0, out vec4 g1, out vec4 g2, out vec4 g3) {
    float n = u_coat_n;
    vec3 V = normalize(u_eye_mm - P);
    if (dot(N, V) < 0.0) {
        N = -N;
    }
    vec3 T2 = cross(N, T1);
    vec3 Vc = into_coat(V, N, n);
    float cv = max(dot(Vc, N), 1e-4);
    float tv = fresnel_t(dot(V, N), n);
    float kd = tv / (COAT_PI * n * n);
    // diffuse base a T(θ_v)/(π n²) under the vertex irradiance with T̄; the lamps' T(θ_l) − T̄ below
    l0 = coat_row(0, 0) * (kd * u_coat_diffuse_t) * e0;
    l1 = coat_row(0, 1) * (kd * u_coat_diffuse_t) * e1;
    l2 = coat_row(0, 2) * (kd * u_coat_diffuse_t) * e2;
    l3 = coat_row(0, 3) * (kd * u_coat_diffuse_t) * e3;
    vec4 dif0 = l0, dif1 = l1, dif2 = l2, dif3 = l3;
    vec4 glints[4] = vec4[4](vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    for (int em = 0; em < u_emitter_count; em++) {
        vec4 t0 = coat_emitter(em, 0);
        vec4 t1 = coat_emitter(em, 1);
        vec4 t2 = coat_emitter(em, 2);
        vec3 c = t0.xyz;
        int kind = int(t0.w + 0.5);
        float hl = t1.w, hw = t2.w;
        // the angular profile toward P, at the emitter's centre (it varies slowly over the lamp)
        float prof = coat_profile(em, acos(clamp(dot(normalize(P - c), t2.xyz), -1.0, 1.0)));
        vec4 w = vec4(0.0);
        vec4 gl = vec4(0.0);
        if (kind == 1) {                          // tube: segments along its axis
            // Lambertian cylinder: radiance I_ref / (2 r ℓ), a segment seen across 2 r seg sin θ_axis
            float seg = 2.0 * hl / float(EMITTER_SEGMENTS);
            float rad = prof / (4.0 * hl * hw * 1e-6);
            for (int i = 0; i < EMITTER_SEGMENTS; i++) {
                vec3 q = c + t1.xyz * (hl * (2.0 * (float(i) + 0.5) / float(EMITTER_SEGMENTS) - 1.0));
                vec3 d = q - P;
                float r2 = dot(d, d);
                vec3 l = d * inversesqrt(r2);
                coat_element(N, T1, T2, Vc, cv, tv, l, 2.0 * hw * seg * length(cross(l, t1.xyz)) / r2, rad, w, gl);
            }
        } else if (kind == 2) {                   // panel: a 4 × 2 grid of cells (Lambertian: I_ref / A)
            vec3 wa = coat_emitter(em, 3).xyz;
            float rad = prof / (4.0 * hl * hw * 1e-6);
            for (int i = 0; i < 4; i++) {
                for (int j = 0; j < 2; j++) {
                    vec3 q = c + t1.xyz * (hl * ((float(i) + 0.5) / 2.0 - 1.0)) + wa * (hw * ((float(j) + 0.5) - 1.0));
                    vec3 d = q - P;
                    float r2 = dot(d, d);
                    vec3 l = d * inversesqrt(r2);
                    coat_element(N, T1, T2, Vc, cv, tv, l, max(dot(-l, t2.xyz), 0.0) * (hl * hw * 0.5) / r2, rad, w, gl);
                }
            }
        } else {                                  // sphere: one element of area π r² (= 4 hw²)
            vec3 d = c - P;
            float r2 = dot(d, d);
            coat_element(N, T1, T2, Vc, cv, tv, d * inversesqrt(r2), 4.0 * hw * hw / r2, prof / (4.0 * hw * hw * 1e-6),
                         w, gl);
        }
        vec4 I0 = coat_emitter(em, 4), I1 = coat_emitter(em, 5), I2 = coat_emitter(em, 6), I3 = coat_emitter(em, 7);
        float kb = kd * w.w;
        l0 += I0 * (coat_row(1, 0) * w.x + coat_row(2, 0) * w.y + coat_row(3, 0) * w.z + coat_row(0, 0) * kb);
        l1 += I1 * (coat_row(1, 1) * w.x + coat_row(2, 1) * w.y + coat_row(3, 1) * w.z + coat_row(0, 1) * kb);
        l2 += I2 * (coat_row(1, 2) * w.x + coat_row(2, 2) * w.y + coat_row(3, 2) * w.z + coat_row(0, 2) * kb);
        l3 += I3 * (coat_row(1, 3) * w.x + coat_row(2, 3) * w.y + coat_row(3, 3) * w.z + coat_row(0, 3) * kb);
        dif0 += I0 * coat_row(0, 0) * kb; dif1 += I1 * coat_row(0, 1) * kb;
        dif2 += I2 * coat_row(0, 2) * kb; dif3 += I3 * coat_row(0, 3) * kb;
        if (em < 4 && gl.x > 0.0) {
            // one glint's radiance factor, with this emitter's level relative to the mean emitter's
            // (the fragment stage multiplies by ρ_f Ī: lamps of one lighting share a spectrum)
            float level = dot(I0 + I1 + I2 + I3, vec4(1.0)) / max(u_lamp_band_sum, 1e-30);
            glints[em] = vec4(gl.x, gl.y / gl.x * level, gl.zw / gl.x);
        }
    }
    float lum_all = dot(l0 + l1 + l2 + l3, vec4(1.0));
    diffuse_share = lum_all > 0.0 ? clamp(dot(dif0 + dif1 + dif2 + dif3, vec4(1.0)) / lum_all, 0.0, 1.0) : 1.0;
    g0 = glints[0];
    g1 = glints[1];
    g2 = glints[2];
    g3 = glints[3];
}
#endif
