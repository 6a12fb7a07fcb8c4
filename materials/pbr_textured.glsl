// Texture-driven PBR inputs; the alpha map makes the material transparent per fragment.
void pbr_textured_visibility() {
    gua_color = albedo * texture(albedo_map, gua_texcoords).rgb;
    gua_roughness = roughness * texture(roughness_map, gua_texcoords).r;
    gua_metalness = metalness;
    gua_alpha = alpha * texture(alpha_map, gua_texcoords).r;
}
