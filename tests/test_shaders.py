import pytest

from rayvr.gl import shaders
from rayvr.gl.shaders import GLSL_DIR, ShaderError, load_source
from test_glsl_constants import import_every_module


def write(root, name, text):
    p = root / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)


def test_includes_resolve_once_and_defines_follow_the_header(tmp_path):
    write(tmp_path, "lib/a.glsl", '#include "b.glsl"\nfloat a() { return b() + 1.0; }\n')
    write(tmp_path, "lib/b.glsl", "float b() { return 2.0; }\n")
    write(tmp_path, "main.comp", '#version 430\n#extension GL_ARB_gpu_shader_int64 : enable\n'
                                 '#include "lib/a.glsl"\n#include "lib/b.glsl"\nvoid main() {}\n')
    src = load_source("main.comp", {"N": 4, "FLAG": True}, root=tmp_path)
    assert src.files == ["main.comp", "lib/a.glsl", "lib/b.glsl"]
    assert src.text.count("float b()") == 1
    lines = src.text.splitlines()
    assert lines[0] == "#version 430"
    assert lines[1:3] == ["#define N 4", "#define FLAG 1"]  # before #if blocks that may hold #extension
    assert lines[4].startswith("#extension")


def test_missing_include_and_missing_version(tmp_path):
    write(tmp_path, "x.comp", '#version 430\n#include "nope.glsl"\n')
    with pytest.raises(ShaderError, match="not found"):
        load_source("x.comp", root=tmp_path)
    write(tmp_path, "y.comp", "void main() {}\n")
    with pytest.raises(ShaderError, match="#version"):
        load_source("y.comp", root=tmp_path)


def test_compile_error_names_the_included_file_and_line(gl, tmp_path):
    write(tmp_path, "common/util.glsl", "// helper\nfloat util() {\n    return undefined_name;\n}\n")
    write(tmp_path, "k.comp", '#version 430\nlayout(local_size_x = 1) in;\n#include "common/util.glsl"\n'
                              'void main() { float x = util(); }\n')
    with pytest.raises(ShaderError) as e:
        shaders.compute(gl.ctx, "k.comp", root=tmp_path)
    assert "glsl/common/util.glsl:3" in str(e.value), str(e.value)
    write(tmp_path, "m.comp", '#version 430\nlayout(local_size_x = 1) in;\n#include "common/ok.glsl"\n'
                              'void main() {\n  int y = ;\n}\n')
    write(tmp_path, "common/ok.glsl", "float ok() { return 1.0; }\n")
    with pytest.raises(ShaderError) as e:
        shaders.compute(gl.ctx, "m.comp", root=tmp_path)
    assert "glsl/m.comp:5" in str(e.value), str(e.value)


def test_every_shipped_shader_compiles(gl):
    """Each compute shader and raster program under rayvr/glsl builds on this driver (with the
    constants every module declares in the header: the module that compiles a shader imports them)."""
    import_every_module()
    for path in sorted(GLSL_DIR.rglob("*.comp")):  # the wavefront kernels take an effect's part
        shaders.compute(gl.ctx, str(path.relative_to(GLSL_DIR)), {"EFFECT_PATHS": "effects/shadows.glsl"}).release()
    for mode in (0, 1):
        shaders.program(gl.ctx, "gbuffer/visibility.vert", "gbuffer/visibility.frag",
                        "gbuffer/visibility.geom" if mode else None, {"LAYER_MODE": mode, "LAYERS": 2}).release()


def test_include_named_by_a_define(tmp_path):
    write(tmp_path, "part/a.glsl", "int part_a() { return 1; }\n")
    write(tmp_path, "main.comp", "#version 430\n#include PART  // the effect's part\nvoid main() {}\n")
    src = load_source("main.comp", {"PART": "part/a.glsl"}, root=tmp_path)
    assert "part_a" in src.text and src.files == ["main.comp", "part/a.glsl"]
    with pytest.raises(ShaderError, match=r"glsl/main.comp:2: #include PART needs the define PART"):
        load_source("main.comp", root=tmp_path)


def test_include_named_by_a_define_with_a_fallback_and_an_absolute_path(tmp_path):
    """`#include NAME or "path"` takes the define's file, else "path" (relative to the including
    file); a define may name an absolute path (a plugin's file outside the root), and a file that
    is not there is one line naming the include that asked for it."""
    root = tmp_path / "root"
    write(root, "lib/default.glsl", "int part_default() { return 0; }\n")
    write(root, "main.comp", '#version 430\n#include PART or "lib/default.glsl"\nvoid main() {}\n')
    assert load_source("main.comp", root=root).files == ["main.comp", "lib/default.glsl"]
    outside = tmp_path / "elsewhere" / "plugin.glsl"
    write(tmp_path, "elsewhere/plugin.glsl", "int part_plugin() { return 2; }\n")
    src = load_source("main.comp", {"PART": str(outside)}, root=root)
    assert "part_plugin" in src.text and "part_default" not in src.text and src.files[1] == str(outside)
    assert src.map_log("0:2(3): error: x\n1:1(5): error: y") == f"glsl/main.comp:2: error: x\n{outside}:1: error: y"
    missing = tmp_path / "gone.glsl"
    with pytest.raises(ShaderError) as e:
        load_source("main.comp", {"PART": str(missing)}, root=root)
    assert str(e.value) == f"glsl/main.comp:2: #include PART (PART = {missing}): shader file not found: {missing}"


def test_an_edited_file_is_read_again(tmp_path):
    """Sources are cached per file version (shaders._lines: mtime and size): a file written again
    with text of another length, even within the filesystem's timestamp tick, gives the new text."""
    write(tmp_path, "e.comp", "#version 430\n// one\n")
    assert "// one" in load_source("e.comp", root=tmp_path).text
    write(tmp_path, "e.comp", "#version 430\n// second\n")
    assert "// second" in load_source("e.comp", root=tmp_path).text
