// Opacity from three sources, as in the guacamole paper's material example:
// an alpha texture, a circular see-through lens in screen space, and distance to the viewer.
void lens_fade_out_visibility() {
    gua_color = albedo;
    gua_roughness = roughness;
    float a = texture(alpha_map, gua_texcoords).r;
    vec2 uv = gua_screen_position / gua_resolution;
    vec2 d = (uv - lens_center) * vec2(gua_resolution.x / gua_resolution.y, 1.0);
    float inside = 1.0 - smoothstep(lens_radius * 0.9, lens_radius, length(d));
    a *= mix(1.0, lens_alpha, inside);
    float dist = length(gua_camera_position - gua_world_position);
    a *= smoothstep(fade_near, fade_far, dist);
    gua_alpha = a;
}
