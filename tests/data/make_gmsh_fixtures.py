"""Make the Gmsh fixtures of tests/test_mesh_io.py with Gmsh itself.

Run from this folder with a Python that has the ``gmsh`` package (not a qsma
dependency; the files below are committed, made with Gmsh 4.15.2):

    python make_gmsh_fixtures.py

Files (coarse on purpose, a few kB each):

- ``gmsh_rect_v41.msh``, ``gmsh_rect_v41_binary.msh``, ``gmsh_rect_v40.msh``,
  ``gmsh_rect_v22.msh``, ``gmsh_rect_v22_binary.msh``: the rectangle [0, 2] x [0, 1] in triangles with physical groups: surface 7 "plate",
  curves 3 "left" (x = 0), 4 "bottom and left", 9 (y = 0, no name), point 5 "origin".
- ``gmsh_rect.inp``: the same mesh exported by Gmsh as Abaqus input (elements of every
  entity as T3D2/CPS3 element sets, groups as *ELSET and *NSET).
- ``gmsh_box_v41.msh``: the unit cube in tetrahedra with volume 1 "solid", surfaces
  2 "bottom" (z = 0) and 3 "top" (z = 1), point 4 "corner" (origin).
"""
import gmsh


def rectangle():
    gmsh.model.add("rectangle")
    surface = gmsh.model.occ.addRectangle(0, 0, 0, 2, 1)
    gmsh.model.occ.synchronize()
    curves = [t for _, t in gmsh.model.getBoundary([(2, surface)], oriented=False)]
    centre = lambda t: gmsh.model.occ.getCenterOfMass(1, t)
    left = [t for t in curves if abs(centre(t)[0]) < 1e-9]
    bottom = [t for t in curves if abs(centre(t)[1]) < 1e-9]
    origin = [t for _, t in gmsh.model.getEntities(0)
              if max(abs(v) for v in gmsh.model.getValue(0, t, [])) < 1e-9]
    gmsh.model.addPhysicalGroup(2, [surface], 7, name="plate")
    gmsh.model.addPhysicalGroup(1, left, 3, name="left")
    gmsh.model.addPhysicalGroup(1, bottom + left, 4, name="bottom and left")
    gmsh.model.addPhysicalGroup(1, bottom, 9)
    gmsh.model.addPhysicalGroup(0, origin, 5, name="origin")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    gmsh.model.mesh.generate(2)
    save("gmsh_rect_v41.msh", 4.1)
    save("gmsh_rect_v41_binary.msh", 4.1, binary=True)
    save("gmsh_rect_v40.msh", 4.0)
    save("gmsh_rect_v22.msh", 2.2)
    save("gmsh_rect_v22_binary.msh", 2.2, binary=True)
    gmsh.option.setNumber("Mesh.SaveGroupsOfNodes", 1)
    gmsh.write("gmsh_rect.inp")
    gmsh.option.setNumber("Mesh.SaveGroupsOfNodes", 0)


def box():
    gmsh.model.add("box")
    volume = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
    gmsh.model.occ.synchronize()
    faces = [t for _, t in gmsh.model.getBoundary([(3, volume)], oriented=False)]
    z = lambda t: gmsh.model.occ.getCenterOfMass(2, t)[2]
    origin = [t for _, t in gmsh.model.getEntities(0)
              if max(abs(v) for v in gmsh.model.getValue(0, t, [])) < 1e-9]
    gmsh.model.addPhysicalGroup(3, [volume], 1, name="solid")
    gmsh.model.addPhysicalGroup(2, [t for t in faces if abs(z(t)) < 1e-9], 2, name="bottom")
    gmsh.model.addPhysicalGroup(2, [t for t in faces if abs(z(t) - 1) < 1e-9], 3, name="top")
    gmsh.model.addPhysicalGroup(0, origin, 4, name="corner")
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    gmsh.model.mesh.generate(3)
    save("gmsh_box_v41.msh", 4.1)


def save(name, version, binary=False):
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", int(binary))
    gmsh.write(name)


if __name__ == "__main__":
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    rectangle()
    box()
    gmsh.finalize()
