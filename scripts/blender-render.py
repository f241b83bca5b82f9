import bpy, sys
import numpy
if not hasattr(numpy, "bool"): numpy.bool = bool
argv = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.render.fps = 25
bpy.ops.import_scene.gltf(filepath=argv[0])
sc = bpy.context.scene
sc.camera = bpy.data.objects["camera"]
sc.frame_set(int(argv[2]))
sc.render.engine = "CYCLES"
sc.cycles.samples = 24
sc.cycles.device = "CPU"
sc.cycles.use_denoising = False
sc.render.resolution_x, sc.render.resolution_y = 640, 480
world = bpy.data.worlds.new("w"); sc.world = world; world.use_nodes = True
world.node_tree.nodes["Background"].inputs[0].default_value = (0.05, 0.12, 0.22, 1)
world.node_tree.nodes["Background"].inputs[1].default_value = 1.0
for l in bpy.data.lights: l.energy = max(l.energy, 3.0)
sc.view_settings.view_transform = "Standard"
sc.render.filepath = argv[1]
bpy.ops.render.render(write_still=True)
