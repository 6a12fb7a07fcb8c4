// glTF 2.0 metallic-roughness inputs, shared by the gltf_opaque, gltf_mask and gltf_blend
// materials (they differ only in what they do with the base colour's alpha).
float gltf_alpha;  // base colour alpha: factor times texture

// glTF colour textures (base colour, emissive) are sRGB-encoded; factors are linear.
vec3 gltf_srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(0.04045, c));
}

// Normal mapping without a tangent attribute: the tangent frame comes from screen-space
// derivatives of position and texture coordinates (Schueler's cotangent frame).
vec3 gltf_perturb_normal(vec3 n, vec3 tangent_normal) {
    vec3 dp1 = dFdx(gua_world_position), dp2 = dFdy(gua_world_position);
    vec2 duv1 = dFdx(gua_texcoords), duv2 = dFdy(gua_texcoords);
    vec3 dp2perp = cross(dp2, n), dp1perp = cross(n, dp1);
    vec3 t = dp2perp * duv1.x + dp1perp * duv2.x;
    vec3 b = dp2perp * duv1.y + dp1perp * duv2.y;
    float m = max(dot(t, t), dot(b, b));
    if (m <= 0.0) return n;  // texture coordinates do not vary here: no frame
    float s = inversesqrt(m);
    return normalize(mat3(t * s, b * s, n) * tangent_normal);
}

void gltf_surface() {
    vec4 texel = texture(base_color_map, gua_texcoords);
    vec4 base = base_color * vec4(gltf_srgb_to_linear(texel.rgb), texel.a);
    gua_color = base.rgb;
    gltf_alpha = base.a;
    vec4 mr = texture(metallic_roughness_map, gua_texcoords);  // roughness in G, metalness in B
    gua_roughness = clamp(roughness * mr.g, 0.0, 1.0);
    gua_metalness = clamp(metallic * mr.b, 0.0, 1.0);
    gua_emissivity = emissive * gltf_srgb_to_linear(texture(emissive_map, gua_texcoords).rgb);
    if (has_normal_map != 0) {
        vec3 tn = texture(normal_map, gua_texcoords).xyz * 2.0 - 1.0;
        tn.xy *= normal_scale;
        gua_normal = gltf_perturb_normal(gua_normal, normalize(tn));
    }
    // last, so the texture lookups above keep their derivatives
    if (double_sided == 0 && !gl_FrontFacing) discard;
}
