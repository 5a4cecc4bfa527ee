// (temporary) keeps the bench library non-empty until the bench files land.
namespace stylerf::bench { int bench_placeholder_symbol = 0; }
