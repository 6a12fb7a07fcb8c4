"""The material GLSL analysis both the transparency decision and the compute rasterizer rely on."""

from guaca_py.materials import glsl


def test_comments_hide_code_from_every_question():
    src = "void m() {\n  // gua_alpha = 0.5; dFdx(x);\n  /* texture(t, uv)\n discard; */ gua_color = vec3(1);\n}"
    code = glsl.strip_comments(src)
    assert code.count("\n") < src.count("\n") and "gua_color" in code
    assert glsl.alpha_writes(code) == []
    assert glsl.fragment_only_feature(code) is None
    assert glsl.implicit_lod_sampling(code) is None


def test_alpha_writes_and_what_the_classifier_cannot_read():
    code = "gua_alpha = 1.0; gua_alpha *= alpha ; if (gua_alpha == 1.0) {}"
    assert glsl.alpha_writes(code) == [("=", "1.0"), ("*=", "alpha")]  # a comparison is no write
    assert all(glsl.is_literal_one(e) for e in ("1", "1.0", "1.f", "(1.0)"))
    assert not any(glsl.is_literal_one(e) for e in ("10", "0.1", "1.5"))
    assert not glsl.alpha_unreadable(code)
    for hidden in ("f(gua_alpha);", "g(x, gua_alpha);", "gua_alpha++;", "--gua_alpha;", "#define A gua_alpha\n"):
        assert glsl.alpha_unreadable(hidden), hidden


def test_fragment_only_features_and_implicit_lod():
    assert glsl.fragment_only_feature("x = fwidthFine(v);") == "fwidthFine"
    assert glsl.fragment_only_feature("if (a) discard;") == "discard"
    assert glsl.fragment_only_feature("float mydFdx = 1.0;") is None  # a name that merely contains one
    assert glsl.implicit_lod_sampling("c = texture(tex, gua_texcoords);") is None
    assert glsl.implicit_lod_sampling("c = texture(tex, gua_texcoords * 2.0);") == "texture"
    assert glsl.implicit_lod_sampling("c = textureProj(tex, p);") == "textureProj"
    assert glsl.implicit_lod_sampling("c = textureLod(tex, uv, 0.0);") is None


def test_texcoord_sampling_becomes_grad_with_comments_and_lines_kept():
    src = "// base colour\nc = texture( albedo ,gua_texcoords);\nd = texture(t, uv);"
    out = glsl.sample_grad_at_texcoords(src)
    assert glsl.samples_at_texcoords(src) and not glsl.samples_at_texcoords(out)
    assert "textureGrad(albedo, gua_texcoords, gua_texcoords_dx, gua_texcoords_dy)" in out
    assert out.startswith("// base colour\n") and out.count("\n") == src.count("\n")
    assert out.endswith("d = texture(t, uv);")


def test_identifiers_and_method_signatures():
    assert glsl.is_identifier("alpha_2") and not glsl.is_identifier("2alpha") and not glsl.is_identifier("a-b")
    assert glsl.defines_void_function("void shade ( ) { }", "shade")
    assert not glsl.defines_void_function("void shade(int x) { }", "shade")
    assert not glsl.defines_void_function("void shader() { }", "shade")
