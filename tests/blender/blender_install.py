"""Installs and enables the add-on package under test inside Blender, as a user would
(shared by blender_import_test.py and blender_modal_test.py).

SPEC["install"] says how:
  "legacy"     the add-on zip through Preferences > Add-ons > Install
               (bpy.ops.preferences.addon_install; Blender 3.4 and later),
               module "isomend_import";
  "extension"  the extension zip through Get Extensions > Install from Disk
               (bpy.ops.extensions.package_install_files into the user
               repository; Blender 4.2 and later), module
               "bl_ext.user_default.isomend_import".
"""
import sys

import addon_utils
import bpy


def install(spec):
    """(module name, module) of the enabled add-on; raises AssertionError if
    Blender did not install or enable it."""
    if spec["install"] == "extension":
        r = bpy.ops.extensions.package_install_files(filepath=spec["package"], repo="user_default",
                                                      enable_on_install=True)
        assert r == {"FINISHED"}, "extension install returned %s" % r
        name = "bl_ext.user_default.isomend_import"
    else:
        bpy.ops.preferences.addon_install(filepath=spec["package"], overwrite=True)
        name = "isomend_import"
        assert addon_utils.enable(name, default_set=True, handle_error=None) is not None, \
            "addon_utils.enable(%r) failed (see the traceback above)" % name
    assert name in bpy.context.preferences.addons.keys(), "%s is not enabled" % name
    assert hasattr(bpy.types, "IMPORT_MESH_OT_slice_stack"), "operator import_mesh.slice_stack not registered"
    module = sys.modules[name]
    print("installed %s (%s) in Blender %s: %s" % (name, spec["install"], bpy.app.version_string,
                                                    module.__file__), flush=True)
    return name, module


def uninstall(name):
    addon_utils.disable(name, default_set=True)
