fn main() {
    let _ = (bindgen::builder, cc::Build::new);
}
