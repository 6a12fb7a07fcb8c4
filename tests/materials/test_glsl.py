"""The material GLSL analysis both the transparency decision and the compute rasterizer rely on."""

import re

import pytest

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


def test_macro_expansion_is_bounded_without_expanding():
    import time

    bomb = "#define A0 x x x x x x x x x x\n"
    bomb += "".join(f"#define A{i + 1} {' '.join([f'A{i}'] * 10)}\n" for i in range(30))  # 10**31 tokens
    t0 = time.perf_counter()
    statements, tokens = glsl.code_size(bomb + "void m() { float y = A30; }")
    assert tokens == glsl.MAX_TOKENS + 1 and statements == 1 and time.perf_counter() - t0 < 0.1
    # function-like macros: the size of each argument counts as often as the body uses it
    square = "#define SQR(x) ((x)*(x))\nvoid m() { float y = SQR(SQR(SQR(a + b))); }"
    assert glsl.code_size(square) == (1, 10 + 73)  # ( ( x ) * ( x ) ): 7 + 2|x|, from |a + b| = 3
    assert glsl.code_size("#ifdef A\n#define N 2\n#else\n#define N 3 + 1\n#endif\nint k = N;") == (1, 7)


def test_macros_that_cannot_be_bounded_are_refused():
    for code, needle in [
        ("#define A B\n#define B A\nA", "macro 'A' expands recursively (A -> B -> A)"),
        ("#define F(x) x(1)\nF(g)", "a macro calls its parameter 'x'"),
        ("#define C(a, b) a##b\nC(x, y)", "token pasting"),
        ("#define ID(x) x\n#define SQR(x) x*x\nID(SQR)(3)", "'SQR' named without its arguments"),
        ("#define M 1\n#define M(x) x\nM", "defined both with and without parameters"),
        ("x = " + "(" * 65 + "1" + ")" * 65 + ";", "brackets nested deeper than 64 levels"),
        ("".join(f"#define B{i} B{i + 1}\n" for i in range(70)) + "B0", "macros nested deeper than 64 levels"),
    ]:
        with pytest.raises(glsl.CodeBoundError, match=re.escape(needle)):
            glsl.code_size(code)


def test_macro_names_read_like_the_preprocessor():
    assert glsl.macro_names("#define A 1\n  #  define B(x) x \\\n + 1\n#define A 2\nint A;") == ["A", "B"]
    assert glsl.tokenize("a+=1.5e-3;b++") == ["a", "+=", "1.5e-3", ";", "b", "++"]
