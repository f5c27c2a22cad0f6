//! Reports: turns a run directory into what people read and use: summary
//! tables, the self-contained HTML report, the Rerun recording and the human
//! review queue of proposed cracks. It may read the outputs of every stage
//! and writes nothing that another stage reads back.
