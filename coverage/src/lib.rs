//! Inspection coverage and replanning: recomputes, voxel by voxel, what the
//! flight actually inspected under the View model (viewing cone, distance
//! band, incidence, occlusion, image quality) against the plan, and plans a
//! follow-up flight for the gaps as a Generalized TSP with its own solver. It
//! owns the coverage tables and the follow-up plan; it reads only the flight
//! model from `ingest`.
