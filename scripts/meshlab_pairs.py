#!/usr/bin/env python3
"""MeshLab's self-intersecting faces of a mesh file, checked exactly.

    PY=/path/to/venv/python; $PY scripts/meshlab_pairs.py MESH.stl

MeshLab (pymeshlab `compute_selection_by_self_intersections_per_face`) tests triangle pairs in
floating point. This takes the faces it selects and tests every pair of them whose boxes
overlap in rational arithmetic (the file's coordinates exactly): pairs without a shared vertex
by separating axes (face normals, edge cross products, in-plane edge normals), pairs sharing an
edge by whether they are coplanar and folded onto each other, pairs sharing a vertex by whether
an edge meets the other triangle anywhere but there. It prints how many pairs really meet.
Conservative: degenerate inputs can only be reported as meeting, never hidden.
"""
import sys, numpy as np, pymeshlab
from fractions import Fraction as Fr
from itertools import combinations
ms = pymeshlab.MeshSet(); ms.load_new_mesh(sys.argv[1])
ms.compute_selection_by_self_intersections_per_face()
m = ms.current_mesh(); F = m.face_matrix(); V = m.vertex_matrix()
idx = list(np.nonzero(m.face_selection_array())[0])
P = lambda j: tuple(Fr(float(c)) for c in V[j])
sub=lambda a,b: tuple(x-y for x,y in zip(a,b)); dot=lambda a,b: sum(x*y for x,y in zip(a,b))
cross=lambda a,b: (a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0])
sgn=lambda x: (x>0)-(x<0)
orient=lambda a,b,c,d: sgn(dot(cross(sub(b,a),sub(c,a)),sub(d,a)))
def sat(A,B):
    ea=[sub(A[(k+1)%3],A[k]) for k in range(3)]; eb=[sub(B[(k+1)%3],B[k]) for k in range(3)]
    na=cross(ea[0],ea[1]); nb=cross(eb[0],eb[1])
    for ax in [na,nb]+[cross(x,y) for x in ea for y in eb]+[cross(na,e) for e in ea]+[cross(nb,e) for e in eb]:
        if ax==(0,0,0): continue
        pa=[dot(ax,p) for p in A]; pb=[dot(ax,p) for p in B]
        if max(pa)<min(pb) or max(pb)<min(pa): return False
    return True
def seg_tri(p,q,T):  # closed segment meets closed triangle
    return sat(T,[p,q,q]) if True else None
def in_cone(v,a,b1,b2,n):  # direction a-v strictly inside or on the cone b1-v..b2-v (coplanar, normal n)
    s1=sgn(dot(cross(sub(b1,v),sub(a,v)),n)); s2=sgn(dot(cross(sub(a,v),sub(b2,v)),n))
    o=sgn(dot(cross(sub(b1,v),sub(b2,v)),n))
    return s1*o>=0 and s2*o>=0 and not (s1==0 and dot(sub(a,v),sub(b1,v))<0) and not (s2==0 and dot(sub(a,v),sub(b2,v))<0)
def improper(i,j):
    fi,fj=list(F[i]),list(F[j]); s=set(fi)&set(fj)
    A=[P(k) for k in fi]; B=[P(k) for k in fj]
    if not s: return sat(A,B)
    if len(s)==2:
        a=P([k for k in fi if k not in s][0]); b=P([k for k in fj if k not in s][0]); e0,e1=[P(k) for k in s]
        if orient(e0,e1,a,b)!=0: return False
        n=cross(sub(e1,e0),sub(a,e0))
        return sgn(dot(cross(sub(e1,e0),sub(a,e0)),n))==sgn(dot(cross(sub(e1,e0),sub(b,e0)),n))
    v=P(list(s)[0]); a1,a2=[P(k) for k in fi if k not in s]; b1,b2=[P(k) for k in fj if k not in s]
    if seg_tri(a1,a2,B) or seg_tri(b1,b2,A): return True
    for (x,T,y1,y2) in [(a1,B,b1,b2),(a2,B,b1,b2),(b1,A,a1,a2),(b2,A,a1,a2)]:
        if orient(T[0],T[1],T[2],x)==0:
            n=cross(sub(T[1],T[0]),sub(T[2],T[0]))
            if in_cone(v,x,y1,y2,n): return True
    return False
real=pairs=0
for i,j in combinations(idx,2):
    A=[P(k) for k in F[i]]; B=[P(k) for k in F[j]]
    if any(max(a[k] for a in A)<min(b[k] for b in B) or max(b[k] for b in B)<min(a[k] for a in A) for k in range(3)): continue
    pairs+=1
    if improper(i,j): real+=1; print("REAL", i, j, F[i], F[j])
print("%s: meshlab faces %d, box-overlapping pairs among them %d, improper pairs (exact) %d" % (sys.argv[1].split('/')[-1], len(idx), pairs, real))
