"""Make the quadratic-element fixtures of tests/test_mesh_validation.py with Gmsh.

Run from this folder with a Python that has the ``gmsh`` package (not a qsma
dependency; the files below are committed, made with Gmsh 4.15.2):

    python make_quadratic_fixtures.py

Files (straight-edged, so every mid-edge, mid-face and centre node lies at the mean of
its corners, which is what the tests check the node order with):

- ``quadratic_box_tet10.msh`` / ``.inp``: the box [0, 1] x [0, 2] x [0, 1] in 10-node
  tetrahedra (Gmsh 4.1; the .inp is Gmsh's own Abaqus export, C3D10), volume "solid",
  surface "bottom" (z = 0).
- ``quadratic_box_hex20.msh`` / ``.inp``: the same box in 2 x 3 x 2 20-node hexahedra
  (C3D20 in the .inp).
- ``quadratic_box_hex27.msh``: the same box in 27-node hexahedra.
- ``quadratic_rect_quad8.msh``: the rectangle [0, 2] x [0, 1] in 4 x 2 8-node quads,
  surface "plate", curve "bottom" (y = 0).
"""
import gmsh


def box(name, hexahedra, incomplete, inp):
    gmsh.model.add(name)
    volume = gmsh.model.occ.addBox(0, 0, 0, 1, 2, 1)
    gmsh.model.occ.synchronize()
    faces = [t for _, t in gmsh.model.getBoundary([(3, volume)], oriented=False)]
    gmsh.model.addPhysicalGroup(3, [volume], 1, name="solid")
    gmsh.model.addPhysicalGroup(2, [t for t in faces
                                    if abs(gmsh.model.occ.getCenterOfMass(2, t)[2]) < 1e-9],
                                2, name="bottom")
    if hexahedra:
        for _, curve in gmsh.model.getEntities(1):
            lo = gmsh.model.getBoundingBox(1, curve)
            length = max(lo[3] - lo[0], lo[4] - lo[1], lo[5] - lo[2])
            gmsh.model.mesh.setTransfiniteCurve(curve, 3 if length < 1.5 else 4)
        for _, surface in gmsh.model.getEntities(2):
            gmsh.model.mesh.setTransfiniteSurface(surface)
            gmsh.model.mesh.setRecombine(2, surface)
        gmsh.model.mesh.setTransfiniteVolume(volume)
    else:
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.8)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.8)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1 if incomplete else 0)
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.setOrder(2)
    save(f"{name}.msh")
    if inp:
        gmsh.write(f"{name}.inp")


def rectangle():
    gmsh.model.add("rect")
    surface = gmsh.model.occ.addRectangle(0, 0, 0, 2, 1)
    gmsh.model.occ.synchronize()
    curves = [t for _, t in gmsh.model.getBoundary([(2, surface)], oriented=False)]
    for curve in curves:
        horizontal = abs(gmsh.model.occ.getCenterOfMass(1, curve)[0] - 1) < 1e-9
        gmsh.model.mesh.setTransfiniteCurve(curve, 5 if horizontal else 3)
    gmsh.model.mesh.setTransfiniteSurface(surface)
    gmsh.model.mesh.setRecombine(2, surface)
    gmsh.model.addPhysicalGroup(2, [surface], 1, name="plate")
    gmsh.model.addPhysicalGroup(1, [t for t in curves
                                    if abs(gmsh.model.occ.getCenterOfMass(1, t)[1]) < 1e-9],
                                2, name="bottom")
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(2)
    save("quadratic_rect_quad8.msh")


def save(name):
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(name)


if __name__ == "__main__":
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    box("quadratic_box_tet10", hexahedra=False, incomplete=False, inp=True)
    box("quadratic_box_hex20", hexahedra=True, incomplete=True, inp=True)
    box("quadratic_box_hex27", hexahedra=True, incomplete=False, inp=False)
    rectangle()
    gmsh.finalize()
